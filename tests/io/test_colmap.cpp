// SPDX-License-Identifier: MIT
// COLMAP IO tests: text and binary round trips, text/binary equivalence on a real model, pose
// conversion, and malformed inputs (truncation at every offset, wrong counts, garbage, absurd
// sizes, unknown models, bad numbers) that must fail with messages naming file and record.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "gs/io/colmap.h"
#include "io_test_util.h"

namespace gs::io {
namespace {

using test::check_error;
using test::TempDir;

ColmapModel sample_model() {
  ColmapModel m;
  m.cameras.push_back({1, "PINHOLE", 640, 480, {500.5, 501.25, 320, 240.125}});
  m.cameras.push_back({7, "OPENCV", 320, 200, {250, 251, 160.5, 99.5, -0.1, 0.01, 0.001, -0.002}});
  ColmapImage a;
  a.id = 3, a.camera_id = 1, a.name = "b.png";
  a.qvec[0] = 0.9, a.qvec[1] = 0.1, a.qvec[2] = -0.3, a.qvec[3] = 0.2;
  a.tvec[0] = 1.0 / 3.0, a.tvec[1] = -2e-7, a.tvec[2] = 12345.678;
  a.points2d = {{{10.5, 20.25}, 0}, {{1e-3, 479.9}, -1}, {{300, 1}, 5}};
  ColmapImage b;
  b.id = 9, b.camera_id = 7, b.name = "sub dir/a.png";  // space: the text NAME is the rest of the line
  ColmapImage c;
  c.id = 4, c.camera_id = 1, c.name = "c.jpg";
  c.qvec[0] = -0.5, c.qvec[1] = 0.5, c.qvec[2] = 0.5, c.qvec[3] = -0.5;
  c.points2d = {{{0.1, 0.2}, 5}};
  m.images = {a, b, c};
  ColmapPoint3D p0;
  p0.id = 0, p0.xyz[0] = 1.5, p0.xyz[1] = -2.25, p0.xyz[2] = 1e10;
  p0.rgb[0] = 255, p0.rgb[1] = 0, p0.rgb[2] = 17, p0.error = 0.123456789;
  p0.track = {{3, 0}};
  ColmapPoint3D p5;
  p5.id = 5, p5.error = 2;
  p5.track = {{3, 2}, {4, 0}};
  ColmapPoint3D p6;  // no track at all
  p6.id = 6;
  m.points = {p0, p5, p6};
  return m;
}

void check_equal(const ColmapModel& a, const ColmapModel& b) {
  REQUIRE(a.cameras.size() == b.cameras.size());
  for (size_t i = 0; i < a.cameras.size(); ++i) {
    CHECK(a.cameras[i].id == b.cameras[i].id);
    CHECK(a.cameras[i].model == b.cameras[i].model);
    CHECK(a.cameras[i].width == b.cameras[i].width);
    CHECK(a.cameras[i].height == b.cameras[i].height);
    CHECK(a.cameras[i].params == b.cameras[i].params);
  }
  REQUIRE(a.images.size() == b.images.size());
  for (size_t i = 0; i < a.images.size(); ++i) {
    const ColmapImage &x = a.images[i], &y = b.images[i];
    CHECK(x.id == y.id);
    CHECK(x.camera_id == y.camera_id);
    CHECK(x.name == y.name);
    for (int k = 0; k < 4; ++k) CHECK(x.qvec[k] == y.qvec[k]);
    for (int k = 0; k < 3; ++k) CHECK(x.tvec[k] == y.tvec[k]);
    REQUIRE(x.points2d.size() == y.points2d.size());
    for (size_t k = 0; k < x.points2d.size(); ++k) {
      CHECK(x.points2d[k].xy[0] == y.points2d[k].xy[0]);
      CHECK(x.points2d[k].xy[1] == y.points2d[k].xy[1]);
      CHECK(x.points2d[k].point3d_id == y.points2d[k].point3d_id);
    }
  }
  REQUIRE(a.points.size() == b.points.size());
  for (size_t i = 0; i < a.points.size(); ++i) {
    const ColmapPoint3D &x = a.points[i], &y = b.points[i];
    CHECK(x.id == y.id);
    for (int k = 0; k < 3; ++k) CHECK(x.xyz[k] == y.xyz[k]);
    for (int k = 0; k < 3; ++k) CHECK(x.rgb[k] == y.rgb[k]);
    CHECK(x.error == y.error);
    REQUIRE(x.track.size() == y.track.size());
    for (size_t k = 0; k < x.track.size(); ++k) {
      CHECK(x.track[k].image_id == y.track[k].image_id);
      CHECK(x.track[k].point2d_idx == y.track[k].point2d_idx);
    }
  }
}

// Binary files of the sample model, by name.
struct BinFiles {
  std::vector<uint8_t> cameras, images, points;
};
BinFiles sample_binary(const TempDir& dir) {
  REQUIRE(write_colmap_binary(sample_model(), dir.path()).ok());
  return {test::read_bytes(dir / "cameras.bin"), test::read_bytes(dir / "images.bin"), test::read_bytes(dir / "points3D.bin")};
}

void put_u64(std::vector<uint8_t>& b, size_t at, uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + size_t(i)] = uint8_t(v >> (8 * i));
}

TEST_CASE("pose_from_colmap and pose_to_colmap invert each other") {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  for (int trial = 0; trial < 100; ++trial) {
    double q[4] = {n01(rng), n01(rng), n01(rng), n01(rng)}, t[3] = {n01(rng), n01(rng), n01(rng)};
    const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const double sign = q[0] < 0 ? -1 : 1;
    for (double& v : q) v *= sign / norm;
    const Pose pose = pose_from_colmap(q, t);
    // R must be orthonormal with det +1 (float precision).
    const float* R = pose.R;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const float dot = R[3 * i] * R[3 * j] + R[3 * i + 1] * R[3 * j + 1] + R[3 * i + 2] * R[3 * j + 2];
        CHECK(dot == doctest::Approx(i == j ? 1.0 : 0.0).epsilon(1e-6));
      }
    double q2[4], t2[3];
    pose_to_colmap(pose, q2, t2);
    for (int k = 0; k < 4; ++k) CHECK(q2[k] == doctest::Approx(q[k]).epsilon(1e-5));
    for (int k = 0; k < 3; ++k) CHECK(t2[k] == doctest::Approx(t[k]).epsilon(1e-6));
  }
  // COLMAP's convention: x_cam = R x_world + t; a 90 degree turn about z maps x to y.
  const double qz[4] = {std::sqrt(0.5), 0, 0, std::sqrt(0.5)}, t0[3] = {0, 0, 0};
  const Pose p = pose_from_colmap(qz, t0);
  CHECK(p.R[3] == doctest::Approx(1.0));  // row 1, column 0
  CHECK(p.R[1] == doctest::Approx(-1.0));
}

TEST_CASE("COLMAP text round trip is exact") {
  TempDir dir;
  const ColmapModel m = sample_model();
  REQUIRE(write_colmap_text(m, dir.path()).ok());
  auto back = read_colmap_text(dir.path());
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  check_equal(m, *back);
  auto any = read_colmap_model(dir.path());
  REQUIRE(any.ok());
  check_equal(m, *any);
}

TEST_CASE("COLMAP binary round trip is exact and read_colmap_model prefers .bin") {
  TempDir dir;
  const ColmapModel m = sample_model();
  REQUIRE(write_colmap_binary(m, dir.path()).ok());
  auto back = read_colmap_binary(dir.path());
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  check_equal(m, *back);
  // A deliberately broken text set next to the binary one must be ignored.
  test::write_text(dir / "cameras.txt", "garbage\n");
  test::write_text(dir / "images.txt", "garbage\n");
  test::write_text(dir / "points3D.txt", "garbage\n");
  auto any = read_colmap_model(dir.path());
  REQUIRE_MESSAGE(any.ok(), any.status().to_string());
  check_equal(m, *any);
}

TEST_CASE("COLMAP writers refuse models they cannot represent") {
  TempDir dir;
  ColmapModel m = sample_model();
  m.cameras[0].params.pop_back();
  check_error(write_colmap_binary(m, dir.path()), {"camera 1", "PINHOLE", "4 parameters"});
  m = sample_model();
  m.cameras[0].model = "WEIRD";
  check_error(write_colmap_text(m, dir.path()), {"WEIRD"});
}

TEST_CASE("sceaux_castle: text and binary models are the same (shared data)") {
  if (!test::have_shared_data("sceaux_castle/sparse/0")) return;
  auto text = read_colmap_model(test::shared_data("sceaux_castle/sparse/0"));
  REQUIRE_MESSAGE(text.ok(), text.status().to_string());
  CHECK(text->cameras.size() == 1);
  CHECK(text->cameras[0].model == "PINHOLE");
  CHECK(text->images.size() == 11);
  CHECK(text->points.size() == 3926);
  TempDir dir;
  REQUIRE(write_colmap_binary(*text, dir / "bin").ok());
  REQUIRE(write_colmap_text(*text, dir / "txt").ok());
  auto bin = read_colmap_binary(dir / "bin");
  REQUIRE_MESSAGE(bin.ok(), bin.status().to_string());
  check_equal(*text, *bin);
  auto txt = read_colmap_text(dir / "txt");
  REQUIRE_MESSAGE(txt.ok(), txt.status().to_string());
  check_equal(*text, *txt);
}

TEST_CASE("binary COLMAP truncated at any offset fails naming file and record and offset") {
  TempDir dir;
  const BinFiles f = sample_binary(dir);
  for (size_t n = 0; n < f.cameras.size(); ++n) {
    std::vector<ColmapCamera> out;
    const Status s = parse_cameras_binary(f.cameras.data(), n, "cameras.bin", &out);
    check_error(s, {"cameras.bin", "byte"});
    CHECK(out.empty());
  }
  for (size_t n = 0; n < f.images.size(); ++n) {
    std::vector<ColmapImage> out;
    check_error(parse_images_binary(f.images.data(), n, "images.bin", &out), {"images.bin", "byte"});
    CHECK(out.empty());
  }
  for (size_t n = 0; n < f.points.size(); ++n) {
    std::vector<ColmapPoint3D> out;
    check_error(parse_points3d_binary(f.points.data(), n, "points3D.bin", &out), {"points3D.bin"});
    CHECK(out.empty());
  }
  // A cut inside the second camera's parameters names that record and where it starts.
  std::vector<ColmapCamera> out;
  const size_t second = 8 + 24 + 4 * 8;  // header + first camera's fixed part + 4 PINHOLE params
  check_error(parse_cameras_binary(f.cameras.data(), second + 60, "cameras.bin", &out),
              {"cameras.bin: record 1 at byte offset " + std::to_string(second), "truncated", "params"});

  // Through the folder reader too: the path of the bad file is in the message.
  auto cut = f.images;
  cut.resize(cut.size() - 5);
  test::write_bytes(dir / "images.bin", cut);
  check_error(read_colmap_model(dir.path()).status(), {dir / "images.bin", "truncated"});
}

TEST_CASE("binary COLMAP with wrong counts or absurd sizes or garbage is refused") {
  TempDir dir;
  const BinFiles f = sample_binary(dir);
  std::vector<ColmapCamera> cams;
  std::vector<ColmapImage> imgs;
  std::vector<ColmapPoint3D> pts;

  auto c = f.cameras;
  put_u64(c, 0, 3);  // one more camera than stored
  check_error(parse_cameras_binary(c.data(), c.size(), "cameras.bin", &cams), {"cameras.bin", "record 2", "truncated"});
  put_u64(c, 0, 1);  // one fewer: the second camera is left over
  check_error(parse_cameras_binary(c.data(), c.size(), "cameras.bin", &cams), {"cameras.bin", "bytes left", "wrong count"});
  put_u64(c, 0, uint64_t(1) << 60);  // would be exabytes: refused before reserving
  check_error(parse_cameras_binary(c.data(), c.size(), "cameras.bin", &cams), {"cameras.bin", "header", "1152921504606846976"});

  c = f.cameras;
  put_u64(c, 8 + 8, 0);  // width 0
  check_error(parse_cameras_binary(c.data(), c.size(), "cameras.bin", &cams), {"record 0", "camera size 0x480"});
  put_u64(c, 8 + 8, 200000);
  check_error(parse_cameras_binary(c.data(), c.size(), "cameras.bin", &cams), {"record 0", "200000x480"});
  c = f.cameras;
  c[8 + 4] = 99;  // model id
  const Status unknown = parse_cameras_binary(c.data(), c.size(), "cameras.bin", &cams);
  check_error(unknown, {"cameras.bin", "record 0", "unknown camera model id 99"});
  CHECK(unknown.code() == StatusCode::kUnsupported);

  auto im = f.images;
  put_u64(im, 0, uint64_t(1) << 40);
  check_error(parse_images_binary(im.data(), im.size(), "images.bin", &imgs), {"images.bin", "claims"});
  im = f.images;
  const size_t name_end = 8 + 4 + 7 * 8 + 4 + std::strlen("b.png") + 1;
  put_u64(im, name_end, uint64_t(1) << 50);  // points2D count of image 0
  check_error(parse_images_binary(im.data(), im.size(), "images.bin", &imgs), {"images.bin", "record 0", "points2D"});
  im = f.images;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(&im[8 + 4 + 8], &nan, 8);  // qx of image 0
  check_error(parse_images_binary(im.data(), im.size(), "images.bin", &imgs), {"images.bin", "record 0", "not finite"});
  im = f.images;
  im[8 + 4 + 7 * 8 + 4 + 1] = 0;  // "b.png" -> "b": the rest shifts and the record no longer parses
  CHECK_FALSE(parse_images_binary(im.data(), im.size(), "images.bin", &imgs).ok());

  auto p = f.points;
  put_u64(p, 8 + 8 + 24 + 3 + 8, uint64_t(1) << 59);  // track length of point 0
  check_error(parse_points3d_binary(p.data(), p.size(), "points3D.bin", &pts), {"points3D.bin", "record 0", "track"});
  p = f.points;
  // Record 1's id follows record 0 (51 fixed bytes + 1 track element): ids 0, 5 -> 0, 0.
  put_u64(p, 8 + 51 + 8, 0);
  check_error(parse_points3d_binary(p.data(), p.size(), "points3D.bin", &pts), {"record 1 at byte offset 67", "duplicate point id 0"});

  // Random garbage never crashes and never yields a model.
  std::mt19937 rng(1);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> junk(size_t(rng() % 300));
    for (uint8_t& b : junk) b = uint8_t(rng());
    if (junk.size() >= 8 && trial % 2) put_u64(junk, 0, 1 + rng() % 3);  // plausible header, junk records
    CHECK_FALSE(parse_cameras_binary(junk.data(), junk.size(), "j", &cams).ok());
    parse_images_binary(junk.data(), junk.size(), "j", &imgs);
    parse_points3d_binary(junk.data(), junk.size(), "j", &pts);
  }
  CHECK(cams.empty());
}

TEST_CASE("binary COLMAP: duplicate ids and links to missing cameras are refused") {
  TempDir dir;
  ColmapModel m = sample_model();
  m.cameras[1].id = 1;
  REQUIRE(write_colmap_binary(m, dir.path()).ok());
  check_error(read_colmap_model(dir.path()).status(), {dir / "cameras.bin", "record 1", "duplicate camera id 1"});
  m = sample_model();
  m.images[2].camera_id = 42;
  REQUIRE(write_colmap_binary(m, dir.path()).ok());
  check_error(read_colmap_model(dir.path()).status(), {dir / "images.bin", "c.jpg", "camera 42"});
}

TEST_CASE("text COLMAP errors name the file and line") {
  std::vector<ColmapCamera> cams;
  const std::string head = "# Camera list\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n1 PINHOLE 400 300 100 100 200 150\n";
  check_error(parse_cameras_text(head + "2 PINHOLE 4OO 300 100 100 200 150\n", "cameras.txt", &cams),
              {"cameras.txt: line 4", "WIDTH", "4OO"});
  check_error(parse_cameras_text(head + "2 PINHOLE 400 300 100 abc 200 150\n", "cameras.txt", &cams),
              {"cameras.txt: line 4", "PARAMS", "abc"});
  check_error(parse_cameras_text(head + "2 PINHOLE 400 300 100 100 200\n", "cameras.txt", &cams),
              {"line 4", "PINHOLE takes 4 parameters, got 3"});
  check_error(parse_cameras_text(head + "\n\n2 PINHOLE 0 300 100 100 200 150\n", "cameras.txt", &cams), {"line 6", "0x300"});
  check_error(parse_cameras_text(head + "1 PINHOLE 400 300 100 100 200 150\n", "cameras.txt", &cams),
              {"line 4", "duplicate camera id 1"});
  const Status unknown = parse_cameras_text(head + "2 FANCY_LENS 400 300 1 2 3\n", "cameras.txt", &cams);
  check_error(unknown, {"line 4", "FANCY_LENS"});
  CHECK(unknown.code() == StatusCode::kUnsupported);
  CHECK(cams.empty());
  REQUIRE(parse_cameras_text(head, "cameras.txt", &cams).ok());
  CHECK(cams.size() == 1);

  std::vector<ColmapImage> imgs;
  const std::string im = "# Image list\n1 1 0 0 0 0 0 0 1 a.png\n1.5 2.5 -1 3 4 7\n";
  REQUIRE(parse_images_text(im, "images.txt", &imgs).ok());
  REQUIRE(imgs.size() == 1);
  CHECK(imgs[0].points2d.size() == 2);
  CHECK(imgs[0].points2d[0].point3d_id == -1);
  // An empty POINTS2D line, and a final image without its POINTS2D line, are both fine.
  REQUIRE(parse_images_text(im + "2 1 0 0 0 0 0 0 1 b.png\n\n3 1 0 0 0 0 0 0 1 c.png\n", "images.txt", &imgs).ok());
  CHECK(imgs.size() == 3);
  CHECK(imgs[1].points2d.empty());
  imgs.clear();
  check_error(parse_images_text(im + "2 1 0 0 0 0 0 0 1 b.png\n1 2 x\n", "images.txt", &imgs), {"images.txt: line 5", "POINT3D_ID", "'x'"});
  check_error(parse_images_text(im + "2 1 0 0 0 0 0 0 1 b.png\n1 2\n", "images.txt", &imgs), {"line 5", "multiple of 3"});
  check_error(parse_images_text(im + "2 nan 0 0 0 0 0 0 1 b.png\n\n", "images.txt", &imgs), {"line 4", "not finite"});
  check_error(parse_images_text(im + "2 0 0 0 0 0 0 0 1 b.png\n\n", "images.txt", &imgs), {"line 4", "zero length"});
  check_error(parse_images_text(im + "2 1 0 0 0 0 0 0 1\n\n", "images.txt", &imgs), {"line 4", "got 9 fields"});
  check_error(parse_images_text(im + "1 1 0 0 0 0 0 0 1 b.png\n\n", "images.txt", &imgs), {"line 4", "duplicate image id 1"});
  CHECK(imgs.empty());

  std::vector<ColmapPoint3D> pts;
  REQUIRE(parse_points3d_text("1 0.5 1 2 10 20 30 0.1 1 0 2 5\n", "points3D.txt", &pts).ok());
  CHECK(pts[0].track.size() == 2);
  check_error(parse_points3d_text("#\n1 0.5 1 2 10 20 300 0.1\n", "points3D.txt", &pts), {"points3D.txt: line 2", "B 300"});
  check_error(parse_points3d_text("1 0.5 1 2 10 20 30 0.1 1\n", "points3D.txt", &pts), {"line 1", "pairs"});
  check_error(parse_points3d_text("1 0.5 1 2 10 20 30 0.1\n1 0 0 0 0 0 0 0\n", "points3D.txt", &pts), {"line 2", "duplicate point id 1"});
}

TEST_CASE("text COLMAP folder: missing files and broken links name the path") {
  TempDir dir;
  check_error(read_colmap_model(dir / "nope").status(), {dir / "nope"});
  check_error(read_colmap_model(dir.path()).status(), {dir.path(), "no complete COLMAP model"});
  ColmapModel m = sample_model();
  m.points[1].track[1].image_id = 77;
  REQUIRE(write_colmap_text(m, dir.path()).ok());
  check_error(read_colmap_model(dir.path()).status(), {dir / "points3D.txt", "point 5", "image 77"});
  test::write_text(dir / "cameras.txt", "1 PINHOLE 640 480 1 1 1\n");
  check_error(read_colmap_model(dir.path()).status(), {dir / "cameras.txt", "line 1", "PINHOLE"});
}

}  // namespace
}  // namespace gs::io
