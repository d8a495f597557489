// SPDX-License-Identifier: MIT
// Which images `--pose-init sfm` hands COLMAP (gs/capture/sfm_images.h): the widest images* copy of
// the dataset within the size limit, with the intrinsics scaled to it; explicit folders checked
// image by image; a broken larger copy passed over with a note, never silently.
#include <doctest/doctest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "gs/capture/sfm_images.h"
#include "gs/io/image.h"
#include "support/temp_dir.h"

namespace gs::capture {
namespace {

namespace fs = std::filesystem;

// Writes views' images at width x height (a gradient, so the file is a real image) into root/folder.
void write_copy(const std::string& root, const std::string& folder, const std::vector<std::string>& names, int width,
                int height) {
  fs::create_directories(root + "/" + folder);
  for (const std::string& name : names) {
    io::Image8 im;
    im.width = width, im.height = height, im.channels = 3;
    im.pixels.resize(size_t(width) * size_t(height) * 3);
    for (size_t i = 0; i < im.pixels.size(); ++i) im.pixels[i] = uint8_t(i * 7);
    REQUIRE(io::write_png(root + "/" + folder + "/" + name, im).ok());
  }
}

struct Views {
  std::vector<io::DatasetView> storage;
  std::vector<const io::DatasetView*> ptrs;
};

// Three views at 8x6 with fx = fy = 10 and the principal point at (4, 3).
Views make_views() {
  Views v;
  for (const char* name : {"a.png", "b.png", "c.png"}) {
    io::DatasetView d;
    d.name = name;
    d.camera.intr = PinholeIntrinsics{10, 10, 4, 3, 8, 6};
    v.storage.push_back(d);
  }
  for (const io::DatasetView& d : v.storage) v.ptrs.push_back(&d);
  return v;
}

TEST_CASE("SfM images: auto takes the widest copy within the size limit and scales the intrinsics") {
  test::TempDir tmp("gs_sfm_images");
  const Views views = make_views();
  const std::vector<std::string> names = {"a.png", "b.png", "c.png"};
  write_copy(tmp.path(), "images", names, 8, 6);
  write_copy(tmp.path(), "images_2", names, 16, 12);
  write_copy(tmp.path(), "images_4", names, 32, 24);
  write_copy(tmp.path(), "images_wide", names, 40, 24);  // another aspect: never a copy of these views
  write_copy(tmp.path(), "other", names, 64, 48);        // not an images* folder

  Expected<SfmImages> big = choose_sfm_images(tmp.path(), "auto", views.ptrs, 40);
  REQUIRE_MESSAGE(big.ok(), big.status().to_string());
  CHECK(fs::path(big->folder).filename() == "images_4");
  REQUIRE(big->images.size() == 3);
  REQUIRE(big->cameras.size() == 3);
  CHECK(big->images[2].width == 32);
  CHECK(big->cameras[1].intr.fx == doctest::Approx(40));
  CHECK(big->cameras[1].intr.cx == doctest::Approx(16));
  CHECK(big->cameras[1].intr.cy == doctest::Approx(12));
  CHECK(big->cameras[1].intr.height == 24);
  CHECK(big->note.empty());

  Expected<SfmImages> limited = choose_sfm_images(tmp.path(), "auto", views.ptrs, 20);  // 32 px is over the limit
  REQUIRE(limited.ok());
  CHECK(fs::path(limited->folder).filename() == "images_2");
  CHECK(limited->cameras[0].intr.fy == doctest::Approx(20));

  Expected<SfmImages> none = choose_sfm_images(tmp.path(), "auto", views.ptrs, 12);  // nothing larger fits
  REQUIRE(none.ok());
  CHECK(none->folder.empty());
  CHECK(none->images.empty());
  CHECK(none->cameras[0].intr.fx == doctest::Approx(10));

  Expected<SfmImages> train = choose_sfm_images(tmp.path(), "train", views.ptrs, 40);
  REQUIRE(train.ok());
  CHECK(train->folder.empty());
  CHECK(train->cameras[2].intr.width == 8);
}

TEST_CASE("SfM images: explicit folders are checked image by image and auto passes a broken copy over with a note") {
  test::TempDir tmp("gs_sfm_images");
  const Views views = make_views();
  write_copy(tmp.path(), "images", {"a.png", "b.png", "c.png"}, 8, 6);
  write_copy(tmp.path(), "images_partial", {"a.png", "b.png"}, 16, 12);
  write_copy(tmp.path(), "images_mixed", {"a.png", "b.png"}, 24, 18);
  write_copy(tmp.path(), "images_mixed", {"c.png"}, 16, 12);

  CHECK(check_sfm_images_choice(tmp.path(), "auto").ok());
  CHECK(check_sfm_images_choice(tmp.path(), "images_partial").ok());
  CHECK(check_sfm_images_choice(tmp.path(), tmp / "images_partial").ok());  // a path works too
  const Status missing_folder = check_sfm_images_choice(tmp.path(), "images_9");
  CHECK(missing_folder.code() == StatusCode::kInvalidArgument);
  CHECK(missing_folder.message().find("images_9 not found") != std::string::npos);

  Expected<SfmImages> partial = choose_sfm_images(tmp.path(), "images_partial", views.ptrs, 1600);
  REQUIRE_FALSE(partial.ok());
  CHECK(partial.status().message().find("c.png") != std::string::npos);

  Expected<SfmImages> mixed = choose_sfm_images(tmp.path(), "images_mixed", views.ptrs, 1600);
  REQUIRE_FALSE(mixed.ok());
  CHECK(mixed.status().message().find("c.png: 16x12 is not the training image's 8x6 scaled uniformly") != std::string::npos);

  // auto: images_mixed is the widest (24 px for the first view) but broken: the training images
  // are used and the note says why.
  Expected<SfmImages> fallback = choose_sfm_images(tmp.path(), "auto", views.ptrs, 1600);
  REQUIRE(fallback.ok());
  CHECK(fallback->folder.empty());
  CHECK(fallback->note.find("images_mixed passed over") != std::string::npos);
}

}  // namespace
}  // namespace gs::capture
