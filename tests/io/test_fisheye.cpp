// SPDX-License-Identifier: MIT
// COLMAP's fisheye camera models (OPENCV_FISHEYE, RADIAL_FISHEYE, SIMPLE_RADIAL_FISHEYE, FOV):
// colmap_project against formulas written here independently, round trips through an inverse
// solved here by bisection, undistortion of a rendered fisheye pattern to a pinhole against the
// pinhole rendering of the same pattern, the valid-pixel map, the automatic field of view, refused
// parameters and read_dataset_files's camera.
#include <algorithm>
#include <cmath>

#include "gs/constants.h"
#include "gs/io/colmap.h"
#include "io_test_util.h"

namespace gs::io {
namespace {

using test::check_error;
using test::TempDir;

// A fisheye in one form for the test: fx fy cx cy and the equidistant polynomial or FOV's omega.
struct Lens {
  double fx, fy, cx, cy;
  double k[4] = {0, 0, 0, 0};
  double omega = -1;  // >= 0: the FOV model
};

Lens lens_of(const ColmapCamera& c) {
  const std::vector<double>& p = c.params;
  if (c.model == "OPENCV_FISHEYE") return {p[0], p[1], p[2], p[3], {p[4], p[5], p[6], p[7]}};
  if (c.model == "RADIAL_FISHEYE") return {p[0], p[0], p[1], p[2], {p[3], p[4], 0, 0}};
  if (c.model == "SIMPLE_RADIAL_FISHEYE") return {p[0], p[0], p[1], p[2], {p[3], 0, 0, 0}};
  return {p[0], p[1], p[2], p[3], {0, 0, 0, 0}, p[4]};  // FOV
}

// COLMAP's documented form, on the pinhole coordinates (a, b) = (x/z, y/z), r = |(a, b)|: the
// equidistant models scale (a, b) by theta_d / r with theta = atan(r); FOV by
// atan(2 r tan(omega / 2)) / (omega r).
void project_reference(const Lens& l, const double ray[3], double* u, double* v) {
  const double a = ray[0] / ray[2], b = ray[1] / ray[2], r = std::sqrt(a * a + b * b);
  double factor;
  if (l.omega >= 0) {
    factor = r < 1e-12 ? 2 * std::tan(l.omega / 2) / l.omega : std::atan(2 * r * std::tan(l.omega / 2)) / (l.omega * r);
  } else {
    // theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8), the powers as products
    // (std::pow was half of this suite's time under qemu).
    const double t = std::atan(r), t2 = t * t, t4 = t2 * t2;
    const double td = t * (1 + l.k[0] * t2 + l.k[1] * t4 + l.k[2] * t4 * t2 + l.k[3] * t4 * t4);
    factor = r < 1e-12 ? 1.0 : td / r;
  }
  *u = l.fx * factor * a + l.cx;
  *v = l.fy * factor * b + l.cy;
}

// The distorted radius at angle theta (reference form above, along one axis).
double radius_at(const Lens& l, double theta) {
  const double ray[3] = {std::sin(theta), 0, std::cos(theta)};
  double u = 0, v = 0;
  project_reference({1, 1, 0, 0, {l.k[0], l.k[1], l.k[2], l.k[3]}, l.omega}, ray, &u, &v);
  return u;
}

// The unit ray of image point (u, v): the angle whose radius is the point's, by bisection in
// [0, max_theta] (the radius rises there) until the interval holds no double between its ends;
// false beyond the radius at max_theta.
bool unproject_reference(const Lens& l, double max_theta, double u, double v, double ray[3]) {
  const double a = (u - l.cx) / l.fx, b = (v - l.cy) / l.fy, rd = std::sqrt(a * a + b * b);
  if (rd > radius_at(l, max_theta)) return false;
  double lo = 0, hi = max_theta;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (mid <= lo || mid >= hi) break;
    (radius_at(l, mid) < rd ? lo : hi) = mid;
  }
  const double t = 0.5 * (lo + hi), s = rd > 0 ? std::sin(t) / rd : 0;
  ray[0] = a * s, ray[1] = b * s, ray[2] = std::cos(t);
  return true;
}

ColmapCamera camera(uint32_t id, const std::string& model, int w, int h, std::vector<double> params) {
  ColmapCamera c;
  c.id = id, c.model = model, c.width = w, c.height = h, c.params = std::move(params);
  return c;
}

TEST_CASE("colmap_project: the fisheye models against COLMAP's formulas, and round trips") {
  const std::vector<ColmapCamera> cams = {
      camera(1, "OPENCV_FISHEYE", 640, 480, {310.5, 305.25, 322.1, 236.7, 0.031, -0.012, 0.004, -0.0007}),
      camera(2, "RADIAL_FISHEYE", 640, 480, {300, 320, 240, -0.05, 0.01}),
      camera(3, "SIMPLE_RADIAL_FISHEYE", 640, 480, {290, 318, 242, 0.02}),
      camera(4, "FOV", 640, 480, {280, 282, 321, 239, 0.93}),
  };
  for (const ColmapCamera& cam : cams) {
    CAPTURE(cam.model);
    CHECK(is_fisheye_model(cam.model));
    const Lens l = lens_of(cam);
    const double valid = fisheye_valid_angle(cam);
    CHECK(valid > 80 * kPi / 180);  // these lenses rise far beyond any pinhole's use
    double worst_projection = 0, worst_angle = 0;
    int n = 0;
    for (int i = 0; i < 40; ++i) {
      for (int j = 0; j < 40; ++j) {
        // Rays up to 80 degrees from the axis in every direction (and the axis itself).
        const double theta = 80 * kPi / 180 * i / 39, phi = 2 * kPi * j / 40;
        const double ray[3] = {3 * std::sin(theta) * std::cos(phi), 3 * std::sin(theta) * std::sin(phi), 3 * std::cos(theta)};
        double u = 0, v = 0, ur = 0, vr = 0;
        REQUIRE(colmap_project(cam, ray, &u, &v));
        project_reference(l, ray, &ur, &vr);
        worst_projection = std::max(worst_projection, std::hypot(u - ur, v - vr));
        double back[3] = {0, 0, 0};
        REQUIRE(unproject_reference(l, valid, u, v, back));
        const double dot = (back[0] * ray[0] + back[1] * ray[1] + back[2] * ray[2]) / 3;
        worst_angle = std::max(worst_angle, std::acos(std::min(1.0, dot)));
        ++n;
      }
    }
    MESSAGE(cam.model << ": worst projection difference " << worst_projection << " px, worst round-trip angle "
                      << worst_angle << " rad over " << n << " rays");
    CHECK(worst_projection < 1e-9);
    CHECK(worst_angle < 1e-7);
    const double behind[3] = {0.1, 0.2, -1};
    double u = 0, v = 0;
    CHECK_FALSE(colmap_project(cam, behind, &u, &v));
  }
  // The pinhole and OpenCV models: u = fx a_d + cx on the pinhole coordinates.
  const ColmapCamera opencv = camera(5, "OPENCV", 64, 48, {50, 51, 32, 24, 0.1, -0.02, 0.003, -0.004});
  const double ray[3] = {0.3, -0.2, 1.5};
  double u = 0, v = 0;
  REQUIRE(colmap_project(opencv, ray, &u, &v));
  const double a = 0.2, b = -0.2 / 1.5, r2 = a * a + b * b, radial = 1 + 0.1 * r2 - 0.02 * r2 * r2;
  CHECK(u == doctest::Approx(50 * (a * radial + 2 * 0.003 * a * b - 0.004 * (r2 + 2 * a * a)) + 32).epsilon(1e-12));
  CHECK(v == doctest::Approx(51 * (b * radial + 2 * -0.004 * a * b + 0.003 * (r2 + 2 * b * b)) + 24).epsilon(1e-12));
  CHECK_FALSE(is_fisheye_model("OPENCV"));
  CHECK(fisheye_valid_angle(opencv) == 0);
  CHECK_FALSE(colmap_project(camera(6, "FULL_OPENCV", 64, 48, std::vector<double>(12, 1.0)), ray, &u, &v));
}

// A smooth pattern on the sphere of directions, 0..255.
double pattern(const double ray[3]) {
  const double n = std::sqrt(ray[0] * ray[0] + ray[1] * ray[1] + ray[2] * ray[2]);
  const double x = ray[0] / n, y = ray[1] / n;
  return 128 + 90 * std::sin(5 * x + 0.3) * std::cos(4 * y - 0.2);
}

// The pattern seen through a camera: each pixel the mean of 4 x 4 samples, unproject(u, v, ray)
// giving each sample's ray (false: black).
template <class Unproject>
Image8 render(int w, int h, Unproject&& unproject) {
  Image8 img{w, h, 3, std::vector<uint8_t>(size_t(w) * size_t(h) * 3)};
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double sum = 0;
      for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
          double ray[3];
          if (unproject(u + (i + 0.5) / 4, v + (j + 0.5) / 4, ray)) sum += pattern(ray);
        }
      for (int c = 0; c < 3; ++c) img.pixels[(size_t(v) * size_t(w) + size_t(u)) * 3 + size_t(c)] = uint8_t(std::lround(sum / 16));
    }
  return img;
}

// Writes a COLMAP dataset of one image with camera `cam` at root.
void write_one(const std::string& root, const ColmapCamera& cam, const Image8& img) {
  std::filesystem::create_directories(root + "/images");
  ColmapModel m;
  m.cameras = {cam};
  ColmapImage im;
  im.id = 1, im.camera_id = cam.id, im.name = "view.png";
  m.images.push_back(im);
  REQUIRE(write_png(root + "/images/view.png", img).ok());
  REQUIRE(write_colmap_text(m, root + "/sparse/0").ok());
}

TEST_CASE("load_dataset: a fisheye image undistorted to a pinhole is the pinhole's image of the same scene") {
  const int W = 96, H = 72;
  const ColmapCamera cam = camera(7, "OPENCV_FISHEYE", W, H, {45, 44, 48.3, 35.7, 0.02, -0.005, 0.001, 0});
  const Lens l = lens_of(cam);
  const Image8 fisheye = render(W, H, [&](double u, double v, double ray[3]) { return unproject_reference(l, kPi / 2, u, v, ray); });
  TempDir dir;
  write_one(dir.path(), cam, fisheye);

  for (const double fov_deg : {70.0, 150.0}) {
    CAPTURE(fov_deg);
    DatasetOptions options;
    options.fisheye_fov_deg = fov_deg;
    auto ds = load_dataset(dir.path(), options);
    REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
    const DatasetView& view = ds->views.at(0);
    const double f = 0.5 * W / std::tan(0.5 * fov_deg * kPi / 180);
    CHECK(view.camera.intr.fx == doctest::Approx(f).epsilon(1e-6));
    CHECK(view.camera.intr.fy == doctest::Approx(f).epsilon(1e-6));
    CHECK(view.camera.intr.cx == doctest::Approx(W / 2.0));
    CHECK(view.camera.intr.cy == doctest::Approx(H / 2.0));
    const Image8 pinhole = render(W, H, [&](double u, double v, double ray[3]) {
      ray[0] = (u - W / 2.0) / f, ray[1] = (v - H / 2.0) / f, ray[2] = 1;
      return true;
    });
    // Valid pixels: those whose centre's position in the fisheye image (reference projection) lies
    // inside it; a pixel within 1e-3 px of the edge may go either way (float positions).
    size_t valid = 0, invalid = 0, unsure = 0;
    double sum = 0, worst = 0;
    for (int v = 0; v < H; ++v)
      for (int u = 0; u < W; ++u) {
        const size_t i = size_t(v) * W + size_t(u);
        const double ray[3] = {(u + 0.5 - W / 2.0) / f, (v + 0.5 - H / 2.0) / f, 1};
        double pu = 0, pv = 0;
        project_reference(l, ray, &pu, &pv);
        const double margin = std::min({pu, W - pu, pv, H - pv});
        const bool expect = margin >= 0;
        const bool got = view.valid.empty() || view.valid.pixels[i] == 255;
        if (std::fabs(margin) < 1e-3) {
          ++unsure;
        } else {
          CHECK(got == expect);
        }
        if (!got) {
          ++invalid;
          CHECK(view.image.pixels[3 * i] == 0);
          continue;
        }
        ++valid;
        // Bilinear resampling of a 4x4-supersampled source needs a margin of a pixel to the source's edge.
        if (margin < 1.0) continue;
        const double e = std::abs(int(view.image.pixels[3 * i]) - int(pinhole.pixels[3 * i]));
        sum += e, worst = std::max(worst, e);
      }
    MESSAGE("fov " << fov_deg << ": " << valid << " valid, " << invalid << " invalid (" << unsure
                   << " at the edge), mean abs error " << sum / double(valid) << ", max " << worst);
    // Measured: fov 70 mean 0.18, max 1; fov 150 mean 0.15, max 1 (levels of 255): bilinear
    // resampling of a smooth pattern, and 8-bit rounding twice.
    CHECK(sum / double(valid) < 0.5);
    CHECK(worst <= 2);
    if (fov_deg == 70.0) CHECK(view.valid.empty());  // every pixel has a source
    if (fov_deg == 150.0) CHECK(invalid > 500);       // the top and bottom rows leave the image
  }
}

TEST_CASE("load_dataset: the automatic fisheye field of view is the widest whose pixels all lie in the image") {
  const int W = 96, H = 72;
  const ColmapCamera cam = camera(3, "SIMPLE_RADIAL_FISHEYE", W, H, {45, 48, 36, 0.02});
  Image8 img{W, H, 3, std::vector<uint8_t>(size_t(W) * H * 3, 200)};
  TempDir dir;
  write_one(dir.path(), cam, img);
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  const double fov = 2 * std::atan(0.5 * W / ds->views[0].camera.intr.fx) * 180 / kPi;
  MESSAGE("automatic field of view " << fov << " degrees");
  CHECK(ds->views[0].valid.empty());
  CHECK(fov < kDefaultFisheyeFovDeg);
  CHECK(fov > 60);
  // The top and bottom rows decide: 0.1 degree wider leaves pixels without a source.
  DatasetOptions wider;
  wider.fisheye_fov_deg = fov + 0.1;
  auto more = load_dataset(dir.path(), wider);
  REQUIRE_MESSAGE(more.ok(), more.status().to_string());
  REQUIRE_FALSE(more->views[0].valid.empty());
  size_t missing = 0;
  for (uint8_t v : more->views[0].valid.pixels) missing += v == 0;
  CHECK(missing > 0);
  // Independently: the centre of the top row's middle pixel at that fov lies above the image.
  const double f = 0.5 * W / std::tan(0.5 * (fov + 0.1) * kPi / 180);
  const double ray[3] = {0.5 / f, (0.5 - H / 2.0) / f, 1};
  double u = 0, v = 0;
  project_reference(lens_of(cam), ray, &u, &v);
  CHECK(v < 0);

  // read_dataset_files gives the stored camera in OPENCV_FISHEYE form (fx fy cx cy first).
  auto files = read_dataset_files(dir.path());
  REQUIRE_MESSAGE(files.ok(), files.status().to_string());
  CHECK(files->views[0].camera.model == "OPENCV_FISHEYE");
  CHECK(files->views[0].camera.params == std::vector<double>{45, 45, 48, 36, 0.02, 0, 0, 0});

  // Downscaled with max_width: the view, its valid map and its camera follow.
  wider.max_width = 48;
  auto half = load_dataset(dir.path(), wider);
  REQUIRE_MESSAGE(half.ok(), half.status().to_string());
  CHECK(half->views[0].valid.width == 48);
  CHECK(half->views[0].valid.height == 36);
  CHECK(half->views[0].camera.intr.fx == doctest::Approx(f / 2).epsilon(1e-6));
}

TEST_CASE("load_dataset: fisheye parameters that cannot describe the needed angles are refused") {
  const int W = 64, H = 48;
  Image8 img{W, H, 3, std::vector<uint8_t>(size_t(W) * H * 3, 100)};
  // theta_d = theta (1 - 0.5 theta^2) stops rising at theta = sqrt(2/3) rad = 46.8 degrees.
  const ColmapCamera folding = camera(7, "OPENCV_FISHEYE", W, H, {30, 30, 32, 24, -0.5, 0, 0, 0});
  CHECK(fisheye_valid_angle(folding) * 180 / kPi == doctest::Approx(46.79).epsilon(1e-3));
  TempDir dir;
  write_one(dir.path(), folding, img);
  DatasetOptions wide;
  wide.fisheye_fov_deg = 120;
  const Status s = load_dataset(dir.path(), wide).status();
  check_error(s, {dir / "sparse/0/cameras.txt", "camera 7", "OPENCV_FISHEYE", "stops growing", "at most"});
  CHECK(s.code() == StatusCode::kInvalidArgument);
  // Automatic: the widest pinhole within both the image and the 46.8 degrees.
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  const double f = ds->views[0].camera.intr.fx;
  const double automatic = 2 * std::atan(0.5 * W / f) * 180 / kPi;
  CHECK(std::atan(std::hypot(W / 2.0 - 0.5, H / 2.0 - 0.5) / f) * 180 / kPi <= 46.8);  // the corner pixels' centres
  // The automatic value given explicitly is accepted (the same rule), 1 degree more is refused.
  DatasetOptions same;
  same.fisheye_fov_deg = automatic;
  CHECK(load_dataset(dir.path(), same).ok());
  same.fisheye_fov_deg = automatic + 1;
  CHECK_FALSE(load_dataset(dir.path(), same).ok());

  TempDir fov;
  write_one(fov.path(), camera(5, "FOV", W, H, {30, 30, 32, 24, 3.5}), img);
  check_error(load_dataset(fov.path()).status(), {"camera 5", "FOV", "omega"});
  TempDir flat;
  write_one(flat.path(), camera(2, "RADIAL_FISHEYE", W, H, {30, 32, 24, -1e4, 0}), img);
  check_error(load_dataset(flat.path()).status(), {"camera 2", "RADIAL_FISHEYE", "below 1 degree"});
  DatasetOptions bad;
  bad.fisheye_fov_deg = 175;
  check_error(load_dataset(flat.path(), bad).status(), {"fisheye field of view", "175"});
}

TEST_CASE("load_dataset: OPENCV pixels that leave the distorted image are marked invalid") {
  // Pincushion distortion (k1 > 0) pushes the corners' sources outside the image: those pixels
  // have no source and are marked; barrel distortion (k1 < 0) keeps every pixel inside.
  const int W = 64, H = 48;
  Image8 img{W, H, 3, std::vector<uint8_t>(size_t(W) * H * 3, 100)};
  TempDir pin;
  write_one(pin.path(), camera(1, "SIMPLE_RADIAL", W, H, {40, 32, 24, 0.3}), img);
  auto ds = load_dataset(pin.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  const Image8& valid = ds->views[0].valid;
  REQUIRE_FALSE(valid.empty());
  CHECK(valid.pixels[0] == 0);                                 // a corner
  CHECK(valid.pixels[size_t(H / 2) * W + size_t(W / 2)] == 255);  // the centre
  CHECK(ds->views[0].image.pixels[0] == 0);
  TempDir barrel;
  write_one(barrel.path(), camera(1, "SIMPLE_RADIAL", W, H, {40, 32, 24, -0.1}), img);
  auto ok = load_dataset(barrel.path());
  REQUIRE_MESSAGE(ok.ok(), ok.status().to_string());
  CHECK(ok->views[0].valid.empty());
}

}  // namespace
}  // namespace gs::io
