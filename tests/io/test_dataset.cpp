// SPDX-License-Identifier: MIT
// load_dataset tests: the real sceaux_castle scene (full size and downscaled), undistortion of a
// synthetic SIMPLE_RADIAL checkerboard, the other supported/refused camera models, and broken
// dataset folders.
#include <algorithm>
#include <cmath>

#include "gs/io/colmap.h"
#include "io_test_util.h"

namespace gs::io {
namespace {

using test::check_error;
using test::TempDir;

// Writes root/sparse/0 (text) with one image per camera entry and root/images/<name>.png.
void write_dataset(const std::string& root, const std::vector<ColmapCamera>& cams, const std::vector<Image8>& images) {
  std::filesystem::create_directories(root + "/images");
  ColmapModel m;
  m.cameras = cams;
  for (size_t i = 0; i < images.size(); ++i) {
    ColmapImage im;
    im.id = uint32_t(i + 1), im.camera_id = cams[i].id, im.name = "view" + std::to_string(i) + ".png";
    im.tvec[2] = double(i);
    m.images.push_back(im);
    REQUIRE(write_png(root + "/images/" + im.name, images[i]).ok());
  }
  ColmapPoint3D p;
  p.id = 1, p.xyz[0] = 0.5, p.rgb[1] = 200;
  m.points.push_back(p);
  REQUIRE(write_colmap_text(m, root + "/sparse/0").ok());
}

double mean_abs_diff(const Image8& a, const Image8& b) {
  REQUIRE(a.pixels.size() == b.pixels.size());
  double s = 0;
  for (size_t i = 0; i < a.pixels.size(); ++i) s += std::abs(int(a.pixels[i]) - int(b.pixels[i]));
  return s / double(a.pixels.size());
}

TEST_CASE("load_dataset: sceaux_castle (shared data)") {
  if (!test::have_shared_data("sceaux_castle/images")) return;
  const std::string root = test::shared_data("sceaux_castle");
  auto ds = load_dataset(root);
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  REQUIRE(ds->views.size() == 11);
  CHECK(ds->points_xyz.size() == 3926 * 3);
  CHECK(ds->points_rgb.size() == 3926 * 3);
  CHECK(ds->points_rgb[0] == 125);  // first point of points3D.txt: 125 133 144
  for (size_t i = 0; i < 11; ++i) {
    const DatasetView& v = ds->views[i];
    CHECK(v.name == "100_71" + std::string(i < 10 ? "0" : "") + std::to_string(i) + ".jpg");
    CHECK(v.camera.intr.width == 400);
    CHECK(v.camera.intr.height == 294);
    CHECK(v.image.width == 400);
    CHECK(v.image.height == 294);
    CHECK(v.image.channels == 3);
    CHECK(v.is_test == (i == 0 || i == 8));
    CHECK(v.camera.intr.fx == doctest::Approx(403.0008019));
    CHECK(v.camera.intr.cy == doctest::Approx(147.25));
  }
  // images.txt lists 100_7101 first (image id 1) and 100_7100 second (id 2): sorting swaps them.
  CHECK(ds->views[0].image_id == 2);
  CHECK(ds->views[1].image_id == 1);
  CHECK(ds->views[0].camera.pose.t[0] == doctest::Approx(6.3938199972207022));

  DatasetOptions half;
  half.max_width = 200;
  half.llffhold = 0;
  auto small = load_dataset(root, half);
  REQUIRE_MESSAGE(small.ok(), small.status().to_string());
  REQUIRE(small->views.size() == 11);
  for (size_t i = 0; i < 11; ++i) {
    const DatasetView& v = small->views[i];
    CHECK(v.camera.intr.width == 200);
    CHECK(v.camera.intr.height == 147);
    CHECK(v.image.width == 200);
    CHECK(v.image.height == 147);
    CHECK_FALSE(v.is_test);
    CHECK(v.camera.intr.fx == doctest::Approx(403.0008019 / 2));
    CHECK(v.camera.intr.fy == doctest::Approx(402.8847417 / 2));
    CHECK(v.camera.intr.cx == doctest::Approx(100));
    CHECK(v.camera.intr.cy == doctest::Approx(73.625));
    CHECK(v.image.pixels == resize_area(ds->views[i].image, 200, 147).pixels);
  }
}

// Checkerboard with 8 px squares, evaluated at an undistorted pixel position (continuous
// coordinates, pixel centres at +0.5).
double checker(double x, double y) { return ((int(std::floor(x / 8)) + int(std::floor(y / 8))) & 1) ? 230.0 : 25.0; }

TEST_CASE("load_dataset undistorts SIMPLE_RADIAL images to a pinhole view") {
  const int W = 96, H = 64, S = 4;  // S x S supersamples per pixel for anti-aliased edges
  const double f = 80, cx = 48, cy = 32, k = -0.2;
  Image8 ideal{W, H, 3, std::vector<uint8_t>(size_t(W) * H * 3)}, distorted = ideal;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      double sum_ideal = 0, sum_dist = 0;
      for (int j = 0; j < S; ++j)
        for (int i = 0; i < S; ++i) {
          const double px = u + (i + 0.5) / S, py = v + (j + 0.5) / S;
          sum_ideal += checker(px, py);
          // This sample is a distorted position: invert x_d = x (1 + k r^2) by fixed-point iteration.
          const double xd = (px - cx) / f, yd = (py - cy) / f;
          double x = xd, y = yd;
          for (int it = 0; it < 50; ++it) {
            const double s = 1 + k * (x * x + y * y);
            x = xd / s, y = yd / s;
          }
          sum_dist += checker(f * x + cx, f * y + cy);
        }
      for (int c = 0; c < 3; ++c) {
        ideal.pixels[(size_t(v) * W + size_t(u)) * 3 + size_t(c)] = uint8_t(std::lround(sum_ideal / (S * S)));
        distorted.pixels[(size_t(v) * W + size_t(u)) * 3 + size_t(c)] = uint8_t(std::lround(sum_dist / (S * S)));
      }
    }

  TempDir dir;
  write_dataset(dir.path(), {{1, "SIMPLE_RADIAL", W, H, {f, cx, cy, k}}}, {distorted});
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  REQUIRE(ds->views.size() == 1);
  const DatasetView& view = ds->views[0];
  CHECK(view.camera.intr.fx == doctest::Approx(f));
  CHECK(view.camera.intr.fy == doctest::Approx(f));
  CHECK(view.camera.intr.cx == doctest::Approx(cx));
  CHECK(view.image.width == W);
  // Resampling (anti-aliased source, then bilinear) smears every checker edge over about two pixels,
  // which dominates a whole-image error, so the geometry is judged on the pixels whose centre is at
  // least 2 px from a square edge: there a correct undistortion reproduces the flat colour.
  double after = 0, before = 0, worst = 0;
  int n = 0;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const double du = std::abs(std::fmod(u + 0.5 + 4.0, 8.0) - 4.0), dv = std::abs(std::fmod(v + 0.5 + 4.0, 8.0) - 4.0);
      if (du < 2.0 || dv < 2.0) continue;
      const size_t i = (size_t(v) * W + size_t(u)) * 3;
      const double e = std::abs(int(view.image.pixels[i]) - int(ideal.pixels[i]));
      after += e, worst = std::max(worst, e), ++n;
      before += std::abs(int(distorted.pixels[i]) - int(ideal.pixels[i]));
    }
  after /= n, before /= n;
  MESSAGE("mean abs error over " << n << " square-interior pixels: distorted " << before << ", undistorted " << after
                                 << " (max " << worst << "); whole image undistorted: " << mean_abs_diff(view.image, ideal));
  // Budget: 1 level of 8-bit rounding per step, observed 0; the distorted input misplaces whole
  // squares towards the corners (observed tens of levels).
  CHECK(after < 1.0);
  CHECK(worst <= 2.0);
  CHECK(before > 10.0);

  // The same distortion as RADIAL (k2 = 0) and OPENCV (k2 = p1 = p2 = 0) gives the same pixels.
  TempDir d2;
  write_dataset(d2.path(), {{1, "RADIAL", W, H, {f, cx, cy, k, 0}}, {2, "OPENCV", W, H, {f, f, cx, cy, k, 0, 0, 0}}},
                {distorted, distorted});
  auto ds2 = load_dataset(d2.path());
  REQUIRE_MESSAGE(ds2.ok(), ds2.status().to_string());
  CHECK(ds2->views[0].image.pixels == view.image.pixels);
  CHECK(ds2->views[1].image.pixels == view.image.pixels);
}

TEST_CASE("load_dataset: undistortion-free models and refused models") {
  Image8 img{16, 12, 3, std::vector<uint8_t>(16 * 12 * 3)};
  for (size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = uint8_t(i * 7);
  TempDir dir;
  write_dataset(dir.path(),
                {{3, "SIMPLE_PINHOLE", 16, 12, {20, 8, 6}}, {4, "OPENCV", 16, 12, {20, 21, 8, 6, 0, 0, 0, 0}}}, {img, img});
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  CHECK(ds->views[0].camera.intr.fy == 20.0f);
  CHECK(ds->views[1].camera.intr.fy == 21.0f);
  CHECK(ds->views[0].image.pixels == img.pixels);
  CHECK(ds->views[1].image.pixels == img.pixels);  // zero distortion: no resampling at all
  CHECK(ds->points_xyz == std::vector<float>{0.5f, 0, 0});

  // The models hbgs does not undistort (the fisheye ones: test_fisheye.cpp).
  TempDir full;
  write_dataset(full.path(), {{5, "FULL_OPENCV", 16, 12, {20, 20, 8, 6, 0.1, 0, 0, 0, 0, 0, 0, 0}}}, {img});
  const Status s = load_dataset(full.path()).status();
  check_error(s, {"FULL_OPENCV", "camera 5"});
  CHECK(s.code() == StatusCode::kUnsupported);
  TempDir prism;
  write_dataset(prism.path(), {{9, "THIN_PRISM_FISHEYE", 16, 12, {20, 20, 8, 6, 0, 0, 0, 0, 0, 0, 0, 0}}}, {img});
  check_error(load_dataset(prism.path()).status(), {"THIN_PRISM_FISHEYE", "camera 9"});
}

TEST_CASE("load_dataset: broken folders name the path") {
  Image8 img{16, 12, 3, std::vector<uint8_t>(16 * 12 * 3, 9)};
  TempDir dir;
  write_dataset(dir.path(), {{1, "PINHOLE", 16, 12, {20, 20, 8, 6}}, {1, "PINHOLE", 16, 12, {20, 20, 8, 6}}}, {img, img});
  // write_dataset wrote camera 1 twice: the reader catches the duplicate.
  check_error(load_dataset(dir.path()).status(), {"cameras.txt", "duplicate camera id 1"});

  TempDir ok;
  write_dataset(ok.path(), {{1, "PINHOLE", 16, 12, {20, 20, 8, 6}}, {2, "PINHOLE", 20, 12, {20, 20, 8, 6}}}, {img, img});
  check_error(load_dataset(ok.path()).status(), {ok / "images/view1.png", "16x12", "expects 20x12"});

  std::filesystem::remove(ok / "images/view1.png");
  check_error(load_dataset(ok.path()).status(), {ok / "images/view1.png", "not found"});
  test::write_text(ok / "images/view1.png", "not a png");
  check_error(load_dataset(ok.path()).status(), {ok / "images/view1.png", "unknown image format"});
  std::filesystem::remove_all(ok / "images");
  check_error(load_dataset(ok.path()).status(), {ok / "images", "not found"});
  check_error(load_dataset(ok / "nowhere").status(), {ok / "nowhere/sparse/0"});
}

}  // namespace
}  // namespace gs::io
