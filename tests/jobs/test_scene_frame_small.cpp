// SPDX-License-Identifier: MIT
// Far and scaled scenes without Embree (so also in the cross builds, under qemu): the generated test
// scene (support/train_scene.h: 8 views of 64 x 48) written as a binary COLMAP dataset, moved by
// 1e7 units and scaled by 1e-3, trains to the original's test PSNR within 0.1 dB, and its exported
// PLY lies where the original's lies after the same move. The full-size version with refined
// poses is test_scene_frame_train (built-in scene, needs hbgs synth).
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <doctest/doctest.h>

#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/io/splat_formats.h"
#include "gs/jobs/export.h"
#include "gs/jobs/train.h"
#include "gs/pose/pose.h"
#include "support/train_scene.h"

namespace {

namespace fs = std::filesystem;

// Writes the scene as a COLMAP dataset (binary: doubles) moved by x' = scale x + shift.
void write_scene(const gs::test::TrainScene& ts, const fs::path& dir, double scale, const double shift[3]) {
  fs::remove_all(dir);
  fs::create_directories(dir / "images");
  fs::create_directories(dir / "sparse" / "0");
  gs::io::ColmapModel m;
  gs::io::ColmapCamera cam;
  cam.id = 1;
  cam.model = "PINHOLE";
  const gs::PinholeIntrinsics& K = ts.views[0].camera.intr;
  cam.width = K.width, cam.height = K.height;
  cam.params = {K.fx, K.fy, K.cx, K.cy};
  m.cameras.push_back(cam);
  for (const gs::io::DatasetView& v : ts.views) {
    REQUIRE(gs::io::write_png((dir / "images" / v.name).string(), v.image).ok());
    gs::io::ColmapImage im;
    im.id = v.image_id;
    im.camera_id = 1;
    im.name = v.name;
    gs::io::pose_to_colmap(v.camera.pose, im.qvec, im.tvec);
    double R[9];
    gs::pose::rotation_from_quaternion(im.qvec, R);
    for (int i = 0; i < 3; ++i)  // the centre moves to scale C + shift
      im.tvec[i] = scale * im.tvec[i] - (R[3 * i] * shift[0] + R[3 * i + 1] * shift[1] + R[3 * i + 2] * shift[2]);
    m.images.push_back(im);
  }
  for (size_t i = 0; i < ts.points.size() / 3; ++i) {
    gs::io::ColmapPoint3D p;
    p.id = i + 1;
    for (int k = 0; k < 3; ++k) p.xyz[k] = scale * double(ts.points[3 * i + size_t(k)]) + shift[k];
    p.rgb[0] = p.rgb[1] = p.rgb[2] = 128;
    m.points.push_back(p);
  }
  REQUIRE(gs::io::write_colmap_binary(m, (dir / "sparse" / "0").string()).ok());
}

struct Outcome {
  double psnr = 0;
  double mean[3] = {0, 0, 0};
};

Outcome train(const fs::path& dataset, const fs::path& out) {
  gs::jobs::TrainRunOptions o;
  o.dataset = dataset.string();
  o.out = (out / "run").string();
  o.iterations = 120;
  o.threads = 1;
  o.eval_every = 0;
  o.checkpoint_every = 0;
  o.save_at = "";
  o.image_features = "none";
  o.offsets = 4;
  o.feature_dim = 16;
  o.max_anchors = 2000;
  gs::jobs::TrainRunSummary s;
  const gs::Status st = gs::jobs::train_run(o, nullptr, &s);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  gs::jobs::ExportRunOptions e;
  e.input = o.out;
  e.out = (out / "model.ply").string();
  e.threads = 1;
  e.sh_degree = 0;
  e.distill_iterations = 0;
  e.evaluate = false;
  REQUIRE(gs::jobs::export_run(e, nullptr).ok());
  gs::Expected<gs::GaussianCloud> ply = gs::io::read_gaussians(e.out);
  REQUIRE(ply.ok());
  Outcome r;
  r.psnr = s.final_eval.psnr;
  for (size_t i = 0; i < ply->size(); ++i)
    for (int k = 0; k < 3; ++k) r.mean[k] += double(ply->means[3 * i + size_t(k)]) / double(ply->size());
  return r;
}

}  // namespace

TEST_CASE("scene frame: training the generated scene moved by 1e7 and scaled by 1e-3 gives the original's PSNR and PLY (reduced, runs under qemu)") {
  const gs::test::TrainScene ts;
  const fs::path tmp = fs::temp_directory_path() / ("gs_scene_frame_small_" + std::to_string(::getpid()));
  const double none[3] = {0, 0, 0};
  write_scene(ts, tmp / "original", 1, none);
  const Outcome original = train(tmp / "original", tmp / "out_original");
  MESSAGE("original: test PSNR " << original.psnr);
  struct Case {
    const char* name;
    double scale, shift[3];
  };
  const Case cases[] = {{"moved 1e7", 1, {1e7, -1e7, 3e6}}, {"scaled 1e-3", 1e-3, {0, 0, 0}}};
  for (const Case& c : cases) {
    CAPTURE(std::string(c.name));
    const fs::path data = tmp / ("data_" + std::to_string(&c - cases));
    write_scene(ts, data, c.scale, c.shift);
    const Outcome moved = train(data, tmp / ("out_" + std::to_string(&c - cases)));
    MESSAGE(std::string(c.name) << ": test PSNR " << moved.psnr << " (original " << original.psnr << ")");
    CHECK(std::abs(moved.psnr - original.psnr) <= 0.1);
    for (int k = 0; k < 3; ++k) CHECK(std::abs(moved.mean[k] - (c.scale * original.mean[k] + c.shift[k])) <= 0.02 * c.scale * 4.6);
  }
  std::error_code ec;
  fs::remove_all(tmp, ec);
}
