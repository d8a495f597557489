// SPDX-License-Identifier: MIT
// load_dataset masks: alpha channels, masks/ in COLMAP's and the same-name (CO3D) naming, mask file
// channel layouts, alpha + mask, masks through undistortion and downscaling, and the errors (a
// missing mask in a dataset with masks/, a mask of the wrong size).
#include <algorithm>
#include <cmath>

#include "gs/io/colmap.h"
#include "io_test_util.h"

namespace gs::io {
namespace {

using test::check_error;
using test::put_jpeg;
using test::put_png;
using test::TempDir;

// A COLMAP text model with one PINHOLE camera of W x H and one image per name (no files written).
void write_model(const std::string& root, int W, int H, const std::vector<std::string>& names,
                 const std::string& model = "PINHOLE", std::vector<double> params = {}) {
  ColmapModel m;
  if (params.empty()) params = {double(W), double(W), W / 2.0, H / 2.0};
  m.cameras.push_back({1, model, W, H, params});
  for (size_t i = 0; i < names.size(); ++i) {
    ColmapImage im;
    im.id = uint32_t(i + 1), im.camera_id = 1, im.name = names[i];
    im.tvec[2] = 1.0 + double(i);
    m.images.push_back(im);
  }
  ColmapPoint3D p;
  p.id = 1;
  m.points.push_back(p);
  REQUIRE(write_colmap_text(m, root + "/sparse/0").ok());
  std::filesystem::create_directories(root + "/images");
}

// W x H image with `channels` channels; pixel value a function of position and channel.
Image8 pattern(int W, int H, int channels, int seed) {
  Image8 img{W, H, channels, std::vector<uint8_t>(size_t(W) * H * channels)};
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < channels; ++c)
        img.pixels[(size_t(y) * W + x) * channels + c] = uint8_t((x * 37 + y * 11 + c * 71 + seed * 13) % 256);
  return img;
}

Image8 channel(const Image8& img, int c) {
  Image8 out{img.width, img.height, 1, std::vector<uint8_t>(size_t(img.width) * img.height)};
  for (size_t i = 0; i < out.pixels.size(); ++i) out.pixels[i] = img.pixels[i * size_t(img.channels) + size_t(c)];
  return out;
}

Image8 rgb_of(const Image8& img) {
  Image8 out{img.width, img.height, 3, std::vector<uint8_t>(size_t(img.width) * img.height * 3)};
  for (size_t i = 0; i < size_t(img.width) * img.height; ++i)
    for (int c = 0; c < 3; ++c) out.pixels[3 * i + size_t(c)] = img.pixels[i * size_t(img.channels) + size_t(c)];
  return out;
}

TEST_CASE("load_dataset: an RGBA image's alpha is the mask and its RGB stays as stored") {
  TempDir dir;
  write_model(dir.path(), 20, 14, {"a.png", "b.png"});
  const Image8 rgba = pattern(20, 14, 4, 1);
  const Image8 rgb = pattern(20, 14, 3, 2);
  put_png(dir / "images/a.png", rgba);
  put_png(dir / "images/b.png", rgb);
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  REQUIRE(ds->views.size() == 2);
  CHECK(ds->views[0].image.channels == 3);
  CHECK(ds->views[0].image.pixels == rgb_of(rgba).pixels);  // not composited, not premultiplied
  CHECK(ds->views[0].mask.channels == 1);
  CHECK(ds->views[0].mask.pixels == channel(rgba, 3).pixels);
  CHECK(ds->views[1].image.pixels == rgb.pixels);
  CHECK(ds->views[1].mask.empty());  // no alpha, no masks/: no mask
  CHECK(ds->layout == DatasetLayout::kColmap);
  CHECK(ds->points_source == PointsSource::kSfm);
}

TEST_CASE("load_dataset: masks/ in COLMAP's naming (<image>.png) and the same-name naming") {
  const Image8 rgb = pattern(16, 12, 3, 3);
  const Image8 grey = pattern(16, 12, 1, 4);
  SUBCASE("COLMAP: masks/<image name>.png, for JPEG images") {
    TempDir dir;
    write_model(dir.path(), 16, 12, {"0001.jpg", "sub/0002.jpg"});
    for (const char* n : {"0001.jpg", "sub/0002.jpg"}) {
      put_jpeg(dir / (std::string("images/") + n), rgb);
      put_png(dir / (std::string("masks/") + n + ".png"), grey);
    }
    auto ds = load_dataset(dir.path());
    REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
    for (const DatasetView& v : ds->views) CHECK(v.mask.pixels == grey.pixels);
  }
  SUBCASE("same name, and the name with its extension replaced by .png (CO3D)") {
    TempDir dir;
    write_model(dir.path(), 16, 12, {"a.png", "b.jpg"});
    put_png(dir / "images/a.png", rgb);
    put_jpeg(dir / "images/b.jpg", rgb);
    put_png(dir / "masks/a.png", grey);
    put_png(dir / "masks/b.png", channel(rgb, 1));
    auto ds = load_dataset(dir.path());
    REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
    CHECK(ds->views[0].mask.pixels == grey.pixels);
    CHECK(ds->views[1].mask.pixels == channel(rgb, 1).pixels);
    // masks_dir "" turns masks off; another folder name is honoured.
    DatasetOptions off;
    off.masks_dir = "";
    auto none = load_dataset(dir.path(), off);
    REQUIRE(none.ok());
    CHECK(none->views[0].mask.empty());
    std::filesystem::rename(dir / "masks", dir / "alpha");
    DatasetOptions other;
    other.masks_dir = "alpha";
    auto renamed = load_dataset(dir.path(), other);
    REQUIRE_MESSAGE(renamed.ok(), renamed.status().to_string());
    CHECK(renamed->views[0].mask.pixels == grey.pixels);
  }
}

TEST_CASE("load_dataset: mask files in grey, RGB, RGBA and 0/1 and alpha with a mask give their minimum") {
  TempDir dir;
  write_model(dir.path(), 4, 1, {"grey.png", "rgb.png", "rgba.png", "binary.png", "both.png"});
  const Image8 rgb{4, 1, 3, std::vector<uint8_t>(12, 50)};
  for (const char* n : {"grey.png", "rgb.png", "rgba.png", "binary.png"}) put_png(dir / (std::string("images/") + n), rgb);
  put_png(dir / "images/both.png", Image8{4, 1, 4, {9, 9, 9, 255, 9, 9, 9, 200, 9, 9, 9, 100, 9, 9, 9, 0}});
  put_png(dir / "masks/grey.png", Image8{4, 1, 1, {0, 1, 128, 255}});
  // Luminance (77 R + 150 G + 29 B) / 256: pure red 76, green 149, blue 28, white 255.
  put_png(dir / "masks/rgb.png", Image8{4, 1, 3, {255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255}});
  // Grey times alpha: white at alpha 255, 128, 0, and grey 100 at alpha 255.
  put_png(dir / "masks/rgba.png", Image8{4, 1, 4, {255, 255, 255, 255, 255, 255, 255, 128, 255, 255, 255, 0, 100, 100, 100, 255}});
  put_png(dir / "masks/binary.png", Image8{4, 1, 1, {0, 1, 1, 0}});
  put_png(dir / "masks/both.png", Image8{4, 1, 1, {255, 150, 255, 255}});
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  auto mask_of = [&](const std::string& name) {
    for (const DatasetView& v : ds->views)
      if (v.name == name) return v.mask.pixels;
    FAIL("no view " << name);
    return std::vector<uint8_t>{};
  };
  CHECK(mask_of("grey.png") == std::vector<uint8_t>{0, 1, 128, 255});  // not all 0/1: kept as levels
  CHECK(mask_of("rgb.png") == std::vector<uint8_t>{76, 149, 28, 255});
  CHECK(mask_of("rgba.png") == std::vector<uint8_t>{255, 128, 0, 100});
  CHECK(mask_of("binary.png") == std::vector<uint8_t>{0, 255, 255, 0});
  CHECK(mask_of("both.png") == std::vector<uint8_t>{255, 150, 100, 0});  // min(alpha, mask)
}

TEST_CASE("load_dataset: a missing or wrong-size mask is an error naming the files") {
  TempDir dir;
  write_model(dir.path(), 16, 12, {"a.png", "b.jpg"});
  put_png(dir / "images/a.png", pattern(16, 12, 3, 1));
  put_jpeg(dir / "images/b.jpg", pattern(16, 12, 3, 1));
  put_png(dir / "masks/a.png", pattern(16, 12, 1, 1));
  // A masks/ folder without b's mask: an error (a silently full mask would train the background).
  const Status missing = load_dataset(dir.path()).status();
  check_error(missing, {dir / "masks", "b.jpg", "image 2 of the COLMAP model", dir / "masks/b.jpg.png", dir / "masks/b.png"});
  CHECK(missing.code() == StatusCode::kIoError);
  put_png(dir / "masks/b.jpg.png", pattern(15, 12, 1, 1));
  const Status wrong = load_dataset(dir.path()).status();
  check_error(wrong, {dir / "masks/b.jpg.png", "15x12", dir / "images/b.jpg", "16x12"});
  CHECK(wrong.code() == StatusCode::kInvalidArgument);
  test::write_text(dir / "masks/b.jpg.png", "not an image");
  check_error(load_dataset(dir.path()).status(), {dir / "masks/b.jpg.png", "unknown image format"});
  // Only the views whose images are decoded read their masks: b (index 1) is a training view.
  DatasetOptions test_only;
  test_only.images = DatasetOptions::Images::kTest;
  auto ds = load_dataset(dir.path(), test_only);
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  CHECK(ds->views[0].is_test);
  CHECK_FALSE(ds->views[0].mask.empty());
  CHECK(ds->views[1].image.empty());
  CHECK(ds->views[1].mask.empty());
}

TEST_CASE("load_dataset: masks follow the image through undistortion and downscaling") {
  // The mask file is the image's green channel, so the loaded mask must be the loaded image's green
  // channel exactly: both take the same resampling map (bilinear, same rounding) and the same area
  // filter.
  const int W = 48, H = 32;
  Image8 img = pattern(W, H, 3, 5);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) img.pixels[(size_t(y) * W + x) * 3 + 1] = ((x / 6 + y / 6) & 1) ? 220 : 30;
  for (const bool distorted : {false, true}) {
    CAPTURE(distorted);
    TempDir dir;
    if (distorted) write_model(dir.path(), W, H, {"v.png"}, "SIMPLE_RADIAL", {40, W / 2.0, H / 2.0, -0.25});
    else write_model(dir.path(), W, H, {"v.png"});
    put_png(dir / "images/v.png", img);
    put_png(dir / "masks/v.png", channel(img, 1));
    for (const int max_width : {0, 20}) {
      CAPTURE(max_width);
      DatasetOptions opt;
      opt.max_width = max_width;
      auto ds = load_dataset(dir.path(), opt);
      REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
      const DatasetView& v = ds->views[0];
      CHECK(v.mask.width == v.image.width);
      CHECK(v.mask.height == v.image.height);
      CHECK(v.mask.width == (max_width ? 20 : W));
      CHECK(v.mask.pixels == channel(v.image, 1).pixels);
      if (distorted && max_width == 0) CHECK(v.mask.pixels != channel(img, 1).pixels);  // it was resampled
    }
  }
}

}  // namespace
}  // namespace gs::io
