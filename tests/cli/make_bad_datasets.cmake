# SPDX-License-Identifier: MIT
# Builds broken copies of the tiny synth scene for the train input-error tests:
#   cmake -DSCENE=<tiny scene> -DSMALL=<scene with smaller images> -DOUT=<folder> -P make_bad_datasets.cmake
# OUT/no_points (points3D.txt without points), OUT/missing_image (images/0001.png deleted),
# OUT/wrong_size (0001.png replaced by a smaller image), OUT/bad_format (0001.png holds text),
# OUT/not_a_model.hbgs (text), OUT/future_model.hbgs (valid signature, format version "cccc"),
# OUT/escape (image 1 named "../../outside.png"), OUT/duplicate (two images named 0000.png),
# OUT/symlink_loop (images/0001.png a symbolic link to itself).
foreach(var SCENE SMALL OUT)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "make_bad_datasets.cmake: -D${var}= is required")
  endif()
endforeach()
file(REMOVE_RECURSE "${OUT}")
foreach(name no_points missing_image wrong_size bad_format escape duplicate symlink_loop)
  file(COPY "${SCENE}/" DESTINATION "${OUT}/${name}")
endforeach()
file(WRITE "${OUT}/no_points/sparse/0/points3D.txt" "# 3D point list with one line of data per point:\n")
file(REMOVE "${OUT}/missing_image/images/0001.png")
file(COPY_FILE "${SMALL}/images/0000.png" "${OUT}/wrong_size/images/0001.png")
file(WRITE "${OUT}/bad_format/images/0001.png" "this is not an image\n")
file(WRITE "${OUT}/not_a_model.hbgs" "this is not a model\n")
file(WRITE "${OUT}/future_model.hbgs" "HBGSMODLcccc")
file(READ "${SCENE}/sparse/0/images.txt" images_txt)
string(REPLACE " 0000.png\n" " ../../outside.png\n" escaped "${images_txt}")
file(WRITE "${OUT}/escape/sparse/0/images.txt" "${escaped}")
string(REPLACE " 0001.png\n" " 0000.png\n" duplicated "${images_txt}")
file(WRITE "${OUT}/duplicate/sparse/0/images.txt" "${duplicated}")
file(REMOVE "${OUT}/symlink_loop/images/0001.png")
file(CREATE_LINK "0001.png" "${OUT}/symlink_loop/images/0001.png" SYMBOLIC)
