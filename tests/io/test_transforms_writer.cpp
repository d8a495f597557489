// SPDX-License-Identifier: MIT
// The transforms.json writer and read_dataset_files: files written by write_transforms_json read
// back through parse_transforms_json and load_dataset with the same poses and intrinsics (shared
// and per-frame, PINHOLE and OPENCV, masks, split lists), the writer's refusals, and the views of
// COLMAP and NeRF-style folders as read_dataset_files describes them.
#include <cmath>
#include <filesystem>

#include "gs/io/colmap.h"
#include "gs/io/transforms.h"
#include "gs/platform/file.h"
#include "io_test_util.h"

namespace gs::io {
namespace {

using test::check_error;
using test::put_png;
using test::TempDir;

Image8 grey_image(int W, int H, int channels, uint8_t value) {
  return Image8{W, H, channels, std::vector<uint8_t>(size_t(W) * size_t(H) * size_t(channels), value)};
}

// A world-to-camera pose per index: a rotation by a different angle about a different axis and a
// translation, so no two frames share a pose.
void pose_of(int i, double q[4], double t[3]) {
  const double angle = 0.3 + 0.7 * i, axis[3] = {std::cos(1.0 + i), std::sin(2.0 * i), 0.5};
  const double n = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
  q[0] = std::cos(angle / 2);
  for (int k = 0; k < 3; ++k) q[k + 1] = std::sin(angle / 2) * axis[k] / n;
  t[0] = 0.1 * i - 0.2, t[1] = 0.3 - 0.05 * i, t[2] = 2.5 + 0.25 * i;
}

TransformsIntrinsics pinhole(double f, double cx, double cy, int w, int h) {
  TransformsIntrinsics in;
  in.fl_x = f, in.fl_y = f * 1.01, in.cx = cx, in.cy = cy, in.w = w, in.h = h;
  return in;
}

// The same pose, compared as world-to-camera rotation matrices (the quaternion's sign is free).
void check_same_pose(const double qa[4], const double ta[3], const double qb[4], const double tb[3], double tolerance) {
  const Pose a = pose_from_colmap(qa, ta), b = pose_from_colmap(qb, tb);
  for (int k = 0; k < 9; ++k) CHECK(std::abs(double(a.R[k]) - double(b.R[k])) <= tolerance);
  for (int k = 0; k < 3; ++k) CHECK(std::abs(ta[k] - tb[k]) <= tolerance);
}

TEST_CASE("write_transforms_json: shared intrinsics read back by parse_transforms_json and load_dataset") {
  TempDir dir;
  const int W = 20, H = 14;
  TransformsFile file;
  double q[5][4], t[5][3];
  for (int i = 0; i < 5; ++i) {
    TransformsFrame f;
    f.file_path = "images/v" + std::to_string(i) + ".png";
    f.mask_path = "masks/v" + std::to_string(i) + ".png";
    f.intrinsics = pinhole(23.5, 10.25, 6.75, W, H);
    pose_of(i, q[i], t[i]);
    transform_matrix_from_pose(q[i], t[i], f.transform_matrix);
    file.frames.push_back(f);
    put_png(dir / f.file_path, grey_image(W, H, 3, uint8_t(30 * i)));
    put_png(dir / f.mask_path, grey_image(W, H, 1, 255));
  }
  file.train_filenames = std::vector<std::string>{"images/v0.png", "images/v1.png", "images/v3.png", "images/v4.png"};
  file.test_filenames = std::vector<std::string>{"images/v2.png"};
  const std::string json = dir / "transforms.json";
  REQUIRE(write_transforms_json(json, file).ok());

  // The text: nerfstudio's keys, the intrinsics once at the top level.
  auto text = platform::read_text_file(json);
  REQUIRE(text.ok());
  CHECK(test::contains(*text, "\"camera_model\": \"PINHOLE\""));
  CHECK(test::contains(*text, "\"fl_x\": 23.5"));
  CHECK(test::contains(*text, "\"w\": 20"));
  CHECK_FALSE(test::contains(*text, "\"k1\""));
  CHECK(test::contains(*text, "\"mask_path\": \"masks/v3.png\""));

  // Parsed back: the same matrices, hence poses, in double.
  TransformsFile parsed;
  REQUIRE(parse_transforms_json(*text, json, &parsed).ok());
  REQUIRE(parsed.frames.size() == 5);
  for (int i = 0; i < 5; ++i) {
    const TransformsFrame& f = parsed.frames[size_t(i)];
    CHECK(f.file_path == file.frames[size_t(i)].file_path);
    CHECK(f.mask_path == file.frames[size_t(i)].mask_path);
    for (int k = 0; k < 16; ++k) CHECK(f.transform_matrix[k] == file.frames[size_t(i)].transform_matrix[k]);
    double qb[4], tb[3];
    REQUIRE(pose_from_transform_matrix(f.transform_matrix, qb, tb).empty());
    check_same_pose(q[i], t[i], qb, tb, 1e-12);
    CHECK(*f.intrinsics.fl_x == 23.5);
    CHECK(*f.intrinsics.fl_y == 23.5 * 1.01);
    CHECK(*f.intrinsics.cx == 10.25);
    CHECK(*f.intrinsics.cy == 6.75);
    CHECK(*f.intrinsics.w == W);
    CHECK(*f.intrinsics.h == H);
  }
  CHECK(*parsed.test_filenames == *file.test_filenames);
  CHECK(*parsed.train_filenames == *file.train_filenames);

  // Loaded as a dataset: the split, the masks and the poses (float) to 1e-6.
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  REQUIRE(ds->views.size() == 5);
  for (int i = 0; i < 5; ++i) {
    const DatasetView& v = ds->views[size_t(i)];
    CHECK(v.name == file.frames[size_t(i)].file_path);
    CHECK(v.is_test == (i == 2));
    CHECK(v.mask.pixels == grey_image(W, H, 1, 255).pixels);
    const Pose expect = pose_from_colmap(q[i], t[i]);
    for (int k = 0; k < 9; ++k) CHECK(std::abs(v.camera.pose.R[k] - expect.R[k]) <= 1e-6f);
    for (int k = 0; k < 3; ++k) CHECK(std::abs(double(v.camera.pose.t[k]) - t[i][k]) <= 1e-6);
    CHECK(v.camera.intr.fx == float(23.5));
    CHECK(v.camera.intr.fy == float(23.5 * 1.01));
    CHECK(v.camera.intr.cx == 10.25f);
    CHECK(v.camera.intr.cy == 6.75f);
    CHECK(v.camera.intr.width == W);
    CHECK(v.camera.intr.height == H);
  }
}

TEST_CASE("write_transforms_json: per-frame intrinsics and OpenCV distortion") {
  TempDir dir;
  TransformsFile file;
  double q[2][4], t[2][3];
  for (int i = 0; i < 2; ++i) {
    TransformsFrame f;
    f.file_path = "f" + std::to_string(i) + ".png";
    f.intrinsics = pinhole(30 + i, 12, 9, 24, 18);
    pose_of(i + 3, q[i], t[i]);
    transform_matrix_from_pose(q[i], t[i], f.transform_matrix);
    file.frames.push_back(f);
    put_png(dir / f.file_path, grey_image(24, 18, 3, 90));
  }
  file.frames[1].intrinsics.k1 = 0.02;
  file.frames[1].intrinsics.p2 = -0.001;
  const std::string json = dir / "transforms.json";
  REQUIRE(write_transforms_json(json, file).ok());
  auto text = platform::read_text_file(json);
  REQUIRE(text.ok());
  CHECK(test::contains(*text, "\"camera_model\": \"OPENCV\""));
  TransformsFile parsed;
  REQUIRE(parse_transforms_json(*text, json, &parsed).ok());
  for (int i = 0; i < 2; ++i) {
    const TransformsIntrinsics& in = parsed.frames[size_t(i)].intrinsics;
    CHECK(*in.fl_x == 30 + i);
    CHECK(in.k1.value_or(-1) == (i == 1 ? 0.02 : 0.0));
    CHECK(in.p2.value_or(-1) == (i == 1 ? -0.001 : 0.0));
  }
  // Without split lists every 8th view by name is a test view; the distorted one loads undistorted.
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  REQUIRE(ds->views.size() == 2);
  CHECK(ds->views[0].is_test);
  CHECK(ds->views[1].camera.intr.fx == 31.0f);
  for (int k = 0; k < 3; ++k) CHECK(std::abs(double(ds->views[1].camera.pose.t[k]) - t[1][k]) <= 1e-6);
}

TEST_CASE("write_transforms_json: refusals name the file, the frame and what is missing") {
  TempDir dir;
  TransformsFrame good;
  good.file_path = "a.png";
  good.intrinsics = pinhole(20, 8, 6, 16, 12);
  const std::string json = dir / "t.json";
  auto refused = [&](TransformsFrame f, std::initializer_list<std::string> needles) {
    TransformsFile file;
    file.frames = {good, f};
    check_error(write_transforms_json(json, file), needles);
    CHECK_FALSE(platform::file_exists(json));  // nothing written
  };
  CHECK(write_transforms_json(json, TransformsFile{}).message().find("no frames") != std::string::npos);
  TransformsFrame f = good;
  f.intrinsics.fl_x.reset();
  refused(f, {json, "frame 1 (a.png)", "no 'fl_x'"});
  f = good;
  f.intrinsics.h.reset();
  refused(f, {"frame 1", "'w' or 'h'"});
  f = good;
  f.intrinsics.cy = std::nan("");
  refused(f, {"frame 1", "not finite"});
  f = good;
  f.intrinsics.k3 = 0.1;
  refused(f, {"frame 1", "k3 and k4"});
  f = good;
  f.transform_matrix[0] = 2;  // scaled rotation
  refused(f, {"frame 1", "not a camera pose", "orthonormal"});
  f = good;
  f.file_path.clear();
  refused(f, {"frame 1", "empty file_path"});

  // transforms_intrinsics: the cameras read_dataset_files gives, and a refused model.
  ColmapCamera cam{4, "OPENCV", 16, 12, {20, 21, 8, 6, 0.1, 0.2, 0.3, 0.4}};
  auto in = transforms_intrinsics(cam);
  REQUIRE(in.ok());
  CHECK(*in->fl_y == 21);
  CHECK(*in->p2 == 0.4);
  CHECK(*in->w == 16);
  check_error(transforms_intrinsics(ColmapCamera{5, "FISHEYE", 16, 12, {20, 8, 6, 0.1}}).status(), {"camera 5 (FISHEYE)"});
}

TEST_CASE("read_dataset_files: a COLMAP folder's views, cameras as stored, masks and split as load_dataset's") {
  TempDir dir;
  const int W = 16, H = 12;
  ColmapModel m;
  m.cameras.push_back({1, "SIMPLE_RADIAL", W, H, {18, 8, 6, 0.01}});
  m.cameras.push_back({2, "PINHOLE", W, H, {20, 21, 8, 6}});
  for (int i = 0; i < 10; ++i) {
    ColmapImage im;
    im.id = uint32_t(20 - i);  // ids against the name order
    im.camera_id = i < 5 ? 1 : 2;
    im.name = "v" + std::to_string(9 - i) + ".png";  // model order against the name order
    pose_of(i, im.qvec, im.tvec);
    m.images.push_back(im);
    put_png(dir / ("images/" + im.name), grey_image(W, H, 3, 77));
    put_png(dir / ("masks/" + im.name + ".png"), grey_image(W, H, 1, 255));
  }
  ColmapPoint3D p;
  p.id = 1;
  m.points.push_back(p);
  REQUIRE(write_colmap_text(m, dir / "sparse/0").ok());

  auto files = read_dataset_files(dir.path());
  REQUIRE_MESSAGE(files.ok(), files.status().to_string());
  auto ds = load_dataset(dir.path());
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  CHECK(files->layout == DatasetLayout::kColmap);
  CHECK(files->model.cameras.size() == 2);
  CHECK(files->model.cameras[0].model == "SIMPLE_RADIAL");  // the model as stored
  CHECK(files->model.points.size() == 1);
  REQUIRE(files->views.size() == ds->views.size());
  for (size_t i = 0; i < files->views.size(); ++i) {
    const DatasetFileView& v = files->views[i];
    CHECK(v.name == ds->views[i].name);
    CHECK(v.is_test == ds->views[i].is_test);
    CHECK(v.image_path == dir / ("images/" + v.name));
    CHECK(v.mask_path == dir / ("masks/" + v.name + ".png"));
    const ColmapImage& im = files->model.images[v.model_image];
    CHECK(im.name == v.name);
    CHECK(im.id == ds->views[i].image_id);
    if (im.camera_id == 1) {
      CHECK(v.camera.model == "OPENCV");
      CHECK(v.camera.params == std::vector<double>{18, 18, 8, 6, 0.01, 0, 0, 0});
    } else {
      CHECK(v.camera.model == "PINHOLE");
      CHECK(v.camera.params == std::vector<double>{20, 21, 8, 6});
    }
    CHECK(v.camera.width == W);
  }
  // No masks folder: no mask paths.
  std::filesystem::remove_all(dir / "masks");
  auto unmasked = read_dataset_files(dir.path());
  REQUIRE(unmasked.ok());
  for (const DatasetFileView& v : unmasked->views) CHECK(v.mask_path.empty());
}

TEST_CASE("read_dataset_files: a transforms file's views as a COLMAP model") {
  TempDir dir;
  TransformsFile file;
  for (int i = 0; i < 3; ++i) {
    TransformsFrame f;
    f.file_path = "./images/r_" + std::to_string(i);  // no extension, as NeRF's synthetic scenes
    f.intrinsics = pinhole(i == 2 ? 40 : 30, 8, 6, 16, 12);
    double q[4], t[3];
    pose_of(i, q, t);
    transform_matrix_from_pose(q, t, f.transform_matrix);
    file.frames.push_back(f);
    put_png(dir / ("images/r_" + std::to_string(i) + ".png"), grey_image(16, 12, 4, 128));
  }
  REQUIRE(write_transforms_json(dir / "transforms_train.json", file).ok());
  // Through the .json path, as the jobs take it.
  auto files = read_dataset_files(dir / "transforms_train.json");
  REQUIRE_MESSAGE(files.ok(), files.status().to_string());
  CHECK(files->layout == DatasetLayout::kTransforms);
  CHECK(files->model.cameras.size() == 2);  // two distinct sets of intrinsics
  CHECK(files->model.points.empty());
  REQUIRE(files->views.size() == 3);
  for (int i = 0; i < 3; ++i) {
    const DatasetFileView& v = files->views[size_t(i)];
    CHECK(v.name == "images/r_" + std::to_string(i) + ".png");
    CHECK(v.image_path == dir / v.name);
    CHECK(v.mask_path.empty());  // RGBA: the alpha is the mask, there is no mask file
    CHECK(v.camera.params[0] == (i == 2 ? 40 : 30));
    const ColmapImage& im = files->model.images[v.model_image];
    CHECK(im.name == v.name);
    double q[4], t[3];
    pose_of(i, q, t);
    check_same_pose(q, t, im.qvec, im.tvec, 1e-12);
  }
  check_error(read_dataset_files(dir / "nothing_here").status(), {"nothing_here"});
}

}  // namespace
}  // namespace gs::io
