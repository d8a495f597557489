# SPDX-License-Identifier: MIT
# Installation of the hbgs libraries as one CMake package and one pkg-config module:
#   <prefix>/include/gs/...                   every library's public headers under one root
#   <prefix>/lib/libgs_*.a                    the libraries
#   <prefix>/lib/cmake/hbgs/hbgsConfig.cmake  find_package(hbgs): hbgs::<lib> and hbgs::hbgs (all)
#   <prefix>/lib/pkgconfig/hbgs.pc            pkg-config --cflags --libs hbgs
#   <prefix>/bin/hbgs                         the command-line program, when it is built
#
# Each library's CMakeLists calls gs_install_library(<target>) once after add_library; the top-level
# CMakeLists calls gs_install_package() once after every library and the apps. A library gs_<name>
# becomes hbgs::<name> (an ALIAS in this build too, for add_subdirectory / FetchContent users).
# GS_INSTALL (default: on when hbgs is the top-level project) turns the install rules off.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

option(GS_INSTALL "Generate the install rules (headers, libraries, CMake package, pkg-config, hbgs)" ${PROJECT_IS_TOP_LEVEL})

# gs_install_library(target): exports target as hbgs::<name> (gs_ prefix dropped) and installs it;
# gs_install_package() later installs the headers of every $<BUILD_INTERFACE:dir> include folder
# of the target inside this source tree (so a library may have several, all holding gs/...).
function(gs_install_library target)
  string(REGEX REPLACE "^gs_" "" name "${target}")
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name})
  add_library(hbgs::${name} ALIAS ${target})
  target_include_directories(${target} PUBLIC $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  set_property(GLOBAL APPEND PROPERTY GS_INSTALLED_LIBRARIES ${target})
  if(GS_INSTALL)
    install(TARGETS ${target} EXPORT hbgsTargets
            ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
            LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
            RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
endfunction()

# gs_install_package(): the umbrella target hbgs::hbgs, the exported targets, hbgsConfig.cmake and
# its version file, hbgs.pc, and the hbgs program. Call once at the end of the top-level CMakeLists.
function(gs_install_package)
  get_property(libs GLOBAL PROPERTY GS_INSTALLED_LIBRARIES)
  add_library(gs_hbgs INTERFACE)
  set_target_properties(gs_hbgs PROPERTIES EXPORT_NAME hbgs)
  target_link_libraries(gs_hbgs INTERFACE ${libs})
  add_library(hbgs::hbgs ALIAS gs_hbgs)
  if(NOT GS_INSTALL)
    return()
  endif()
  install(TARGETS gs_hbgs EXPORT hbgsTargets)

  # Headers: every library's own include folders into the one include root.
  set(header_dirs)
  foreach(t IN LISTS libs)
    get_target_property(dirs ${t} INTERFACE_INCLUDE_DIRECTORIES)
    foreach(d IN LISTS dirs)
      if(d MATCHES "^\\$<BUILD_INTERFACE:(.+)>$")
        set(d "${CMAKE_MATCH_1}")
        cmake_path(IS_PREFIX PROJECT_SOURCE_DIR "${d}" NORMALIZE inside)
        if(inside AND IS_DIRECTORY "${d}" AND NOT d IN_LIST header_dirs)
          list(APPEND header_dirs "${d}")
        endif()
      endif()
    endforeach()
  endforeach()
  foreach(d IN LISTS header_dirs)
    install(DIRECTORY "${d}/" DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.h" PATTERN "*.hpp")
  endforeach()

  set(cmake_dir ${CMAKE_INSTALL_LIBDIR}/cmake/hbgs)
  install(EXPORT hbgsTargets NAMESPACE hbgs:: DESTINATION ${cmake_dir})

  # What the exported targets need from the consumer's side (see hbgsConfig.cmake.in).
  set(GS_CONFIG_COMPONENTS)
  foreach(t IN LISTS libs)
    string(REGEX REPLACE "^gs_" "" name "${t}")
    list(APPEND GS_CONFIG_COMPONENTS ${name})
  endforeach()
  set(GS_CONFIG_NEEDS_JSON OFF)
  if(TARGET gs_capture OR TARGET gs_jobs)
    set(GS_CONFIG_NEEDS_JSON ON)
  endif()
  foreach(flag GS_WITH_V4L2 GS_WITH_LIBCAMERA GS_WITH_LIBAV)
    if(NOT DEFINED ${flag} OR NOT TARGET gs_capture)
      set(${flag} OFF)
    endif()
  endforeach()
  if(NOT DEFINED GS_WITH_ZLIB OR NOT TARGET gs_io)
    set(GS_WITH_ZLIB OFF)
  endif()
  if(NOT DEFINED GS_WITH_ZSTD OR NOT TARGET gs_io)
    set(GS_WITH_ZSTD OFF)
  endif()
  configure_package_config_file(${CMAKE_CURRENT_FUNCTION_LIST_DIR}/hbgsConfig.cmake.in
                                ${PROJECT_BINARY_DIR}/hbgsConfig.cmake INSTALL_DESTINATION ${cmake_dir})
  # 0.x: a minor version may change the API, so only the same major.minor is compatible.
  write_basic_package_version_file(${PROJECT_BINARY_DIR}/hbgsConfigVersion.cmake
                                   VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
  install(FILES ${PROJECT_BINARY_DIR}/hbgsConfig.cmake ${PROJECT_BINARY_DIR}/hbgsConfigVersion.cmake
          DESTINATION ${cmake_dir})

  # pkg-config: static libraries, so Libs lists each one, dependants first (libraries register
  # after the ones they link, so the reverse registration order is a valid link order), then the
  # system libraries; the optional capture backends come in through Requires.
  set(pc_libs "-L\${libdir}")
  set(reversed ${libs})
  list(REVERSE reversed)
  foreach(t IN LISTS reversed)
    get_target_property(out ${t} OUTPUT_NAME)
    if(NOT out)
      set(out ${t})
    endif()
    string(APPEND pc_libs " -l${out}")
  endforeach()
  string(APPEND pc_libs " -lpthread")
  set(pc_cflags "-I\${includedir}")
  set(pc_requires)
  if(GS_WITH_V4L2)
    string(APPEND pc_cflags " -DGS_HAVE_V4L2=1")
  endif()
  if(GS_WITH_LIBCAMERA)
    string(APPEND pc_cflags " -DGS_HAVE_LIBCAMERA=1")
    list(APPEND pc_requires libcamera)
  endif()
  if(GS_WITH_LIBAV)
    string(APPEND pc_cflags " -DGS_HAVE_LIBAV=1")
    list(APPEND pc_requires libavformat libavcodec libavutil libswscale)
  endif()
  if(GS_WITH_ZLIB)
    list(APPEND pc_requires zlib)
  endif()
  if(GS_WITH_ZSTD)
    list(APPEND pc_requires libzstd)
  endif()
  list(JOIN pc_requires " " pc_requires)
  if(pc_requires)
    set(pc_requires "Requires: ${pc_requires}\n")
  endif()
  # ${pcfiledir} keeps the file relocatable (a copied prefix, an unpacked .deb).
  file(RELATIVE_PATH pc_up "/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/")
  string(REGEX REPLACE "/$" "" pc_up "${pc_up}")
  file(WRITE ${PROJECT_BINARY_DIR}/hbgs.pc
"prefix=\${pcfiledir}/${pc_up}
libdir=\${prefix}/${CMAKE_INSTALL_LIBDIR}
includedir=\${prefix}/${CMAKE_INSTALL_INCLUDEDIR}

Name: hbgs
Description: Hybrid bundle-adjusting 3D Gaussian splatting on the CPU (static libraries, C++17)
Version: ${PROJECT_VERSION}
${pc_requires}Cflags: ${pc_cflags}
Libs: ${pc_libs}
")
  install(FILES ${PROJECT_BINARY_DIR}/hbgs.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

  # The program (it links the libraries statically; Embree, libav and libcamera are shared).
  if(TARGET hbgs)
    install(TARGETS hbgs RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
  if(TARGET hbgs-device)  # the on-device commands without FFmpeg, libcamera and Embree
    install(TARGETS hbgs-device RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
endfunction()
