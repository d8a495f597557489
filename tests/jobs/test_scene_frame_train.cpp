// SPDX-License-Identifier: MIT
// Far and scaled scenes train like the original (gs/scene_frame.h): the built-in scene at a reduced
// size, moved by 1e5, 1e6 and 1e7 units and scaled by 1e-3 and 1e3 (written as binary COLMAP, doubles),
// trains to the original's test PSNR within 0.25 dB (without growth, which is chaotic in a run this
// short: train_and_export), and what the run writes for the user is in the user's frame: the
// exported PLY's Gaussians and the refined poses.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <string>
#include <vector>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/splat_formats.h"
#include "gs/jobs/export.h"
#include "gs/jobs/train.h"
#include "gs/pose/pose.h"
#include "support/run_command.h"

namespace {

namespace fs = std::filesystem;

using gs::test::run;

fs::path fresh(const std::string& name) { return gs::test::fresh_dir(GS_TEST_TMP, name); }

// The user's change of frame: x' = scale x + shift.
struct Move {
  const char* name;
  double scale;
  double shift[3];
};

void camera_centre(const gs::io::ColmapImage& im, double c[3]) {
  double R[9];
  gs::pose::rotation_from_quaternion(im.qvec, R);
  for (int k = 0; k < 3; ++k) c[k] = -(R[k] * im.tvec[0] + R[3 + k] * im.tvec[1] + R[6 + k] * im.tvec[2]);
}

// The dataset at `from` moved as m into `to` (binary COLMAP, so every double survives; the images
// folder is a link to the original's).
void write_moved(const fs::path& from, const fs::path& to, const Move& m) {
  gs::Expected<gs::io::ColmapModel> model = gs::io::read_colmap_model((from / "sparse" / "0").string());
  REQUIRE_MESSAGE(model.ok(), model.status().to_string());
  for (gs::io::ColmapImage& im : model->images) {
    double R[9];
    gs::pose::rotation_from_quaternion(im.qvec, R);
    for (int i = 0; i < 3; ++i)  // t' = scale t - R shift (the centre moves to scale C + shift)
      im.tvec[i] = m.scale * im.tvec[i] - (R[3 * i] * m.shift[0] + R[3 * i + 1] * m.shift[1] + R[3 * i + 2] * m.shift[2]);
  }
  for (gs::io::ColmapPoint3D& p : model->points)
    for (int k = 0; k < 3; ++k) p.xyz[k] = m.scale * p.xyz[k] + m.shift[k];
  fs::create_directories(to / "sparse" / "0");
  REQUIRE(gs::io::write_colmap_binary(*model, (to / "sparse" / "0").string()).ok());
  fs::create_directory_symlink(fs::absolute(from / "images"), to / "images");
}

struct Outcome {
  double psnr = 0;
  gs::GaussianCloud ply;
  gs::io::ColmapModel refined;
};

// Test PSNR of a moved or scaled scene against its reference run, dB (see train_and_export).
constexpr double kPsnrTolerance = 0.25;

gs::jobs::TrainRunOptions short_run(const std::string& dataset, const fs::path& out, int iterations) {
  gs::jobs::TrainRunOptions o;
  o.dataset = dataset;
  o.out = out.string();
  o.iterations = iterations;
  o.threads = 1;
  o.eval_every = 0;
  o.checkpoint_every = 0;
  o.save_at = "";
  o.seed = 3;
  return o;
}

// A training run (test PSNR) exported as a PLY, then a short run with noisy poses refined
// (refined_poses/; the noise is relative to the scene, so the same in every frame).
Outcome train_and_export(const std::string& dataset, const fs::path& out) {
  Outcome r;
  gs::jobs::TrainRunOptions o = short_run(dataset, out / "run", 300);
  // No growth: its threshold decisions make a run this short chaotic. The last-bit differences the
  // recentring leaves in the input far out (a pose's translation is t + R centre in double)
  // moved the test PSNR by up to 1.2 dB with growth on (seeds 3-6, avx2 and sse2), about as much as
  // the seed does; without it by up to 0.07 dB then, and by 0.105 dB (1e5) and 0.102 dB (1e7) on
  // avx2 with 7 offsets per anchor (2026-12-07). Hence kPsnrTolerance. Without the frame (every
  // scene trained where the user put it) the 1e7 case fails every check (4.5 dB lower, the PLY's
  // mean and scale and the refined poses off) and the 1e6 case the PSNR (1.2 dB lower) and scale
  // checks, while the 1e5 case passes (float keeps 1/128 of a unit there, finer than this 64x48
  // scene needs). The initial anchors still lie on the frame's voxel grid.
  o.gaussians_per_pixel = 1e-9;
  gs::jobs::TrainRunSummary s;
  const gs::Status st = gs::jobs::train_run(o, nullptr, &s);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  r.psnr = s.final_eval.psnr;
  gs::jobs::ExportRunOptions e;
  e.input = o.out;
  e.out = (out / "model.ply").string();
  e.threads = 1;
  e.sh_degree = 0;
  e.distill_iterations = 0;
  e.evaluate = false;
  gs::jobs::ExportRunSummary es;
  const gs::Status est = gs::jobs::export_run(e, &es);
  REQUIRE_MESSAGE(est.ok(), est.to_string());
  gs::Expected<gs::GaussianCloud> ply = gs::io::read_gaussians(e.out);
  REQUIRE_MESSAGE(ply.ok(), ply.status().to_string());
  r.ply = std::move(ply).value();

  gs::jobs::TrainRunOptions p = short_run(dataset, out / "posed", 60);
  p.pose_noise = "rot:1,trans:0.01,seed:2";
  p.optimize_poses = true;
  const gs::Status pst = gs::jobs::train_run(p, nullptr, nullptr);
  REQUIRE_MESSAGE(pst.ok(), pst.to_string());
  gs::Expected<gs::io::ColmapModel> refined = gs::io::read_colmap_text((fs::path(p.out) / "refined_poses").string());
  REQUIRE_MESSAGE(refined.ok(), refined.status().to_string());
  r.refined = std::move(refined).value();
  return r;
}

// The mean of the Gaussians' means and their median log-scale, in double.
void cloud_stats(const gs::GaussianCloud& c, double mean[3], double* median_log_scale) {
  mean[0] = mean[1] = mean[2] = 0;
  for (size_t i = 0; i < c.size(); ++i)
    for (int k = 0; k < 3; ++k) mean[k] += double(c.means[3 * i + size_t(k)]) / double(c.size());
  std::vector<float> s = c.log_scales;
  std::nth_element(s.begin(), s.begin() + std::ptrdiff_t(s.size() / 2), s.end());
  *median_log_scale = s[s.size() / 2];
}

}  // namespace

TEST_CASE("scene frame: training the built-in scene moved by 1e5, 1e6 and 1e7 and scaled by 1e-3 and 1e3 gives the original's PSNR, PLY and refined poses in the user's frame") {
  const fs::path tmp = fresh("scene_frame_train");
  const fs::path base = tmp / "base";
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + base.string() +
              " --width 64 --height 48 --views-arc 6 --views-orbit 10 --points 1500 --seed 1 --threads 1") == 0);
  gs::Expected<gs::io::ColmapModel> truth = gs::io::read_colmap_model((base / "sparse" / "0").string());
  REQUIRE(truth.ok());
  double extent = 0, mean_c[3] = {0, 0, 0};
  for (const gs::io::ColmapImage& im : truth->images) {
    double c[3];
    camera_centre(im, c);
    for (int k = 0; k < 3; ++k) mean_c[k] += c[k] / double(truth->images.size());
  }
  for (const gs::io::ColmapImage& im : truth->images) {
    double c[3];
    camera_centre(im, c);
    extent = std::max(extent, std::hypot(c[0] - mean_c[0], c[1] - mean_c[1], c[2] - mean_c[2]));
  }

  const Outcome original = train_and_export(base.string(), tmp / "original");
  MESSAGE("original: test PSNR " << std::setprecision(6) << original.psnr << " dB, " << original.ply.size() << " Gaussians");

  // Each case against the run it must reproduce: the original, or (for a move off the recentring
  // grid) the original moved by the same remainder, which places the anchor voxel grid alike.
  const Move near_037 = {"moved 0.37 (an ordinary scene: not recentred)", 1, {0.37, 0.37, -0.37}};
  const fs::path near_dir = tmp / "near_037";
  write_moved(base, near_dir / "scene", near_037);
  const Outcome near = train_and_export((near_dir / "scene").string(), near_dir);
  MESSAGE(std::string(near_037.name) << ": test PSNR " << near.psnr << " dB");
  struct Case {
    Move move;
    const Outcome* reference;
    Move reference_move;
  };
  const Move unmoved = {"original", 1, {0, 0, 0}};
  const Case cases[] = {{{"moved 1e5", 1, {1e5, -1e5, 5e4}}, &original, unmoved},
                        {{"moved 1e6", 1, {-1e6, 1e6, 1e6}}, &original, unmoved},
                        {{"moved 1e7", 1, {1e7, 1e7, -1e7}}, &original, unmoved},
                        {{"scaled 1e-3", 1e-3, {0, 0, 0}}, &original, unmoved},
                        {{"scaled 1e3", 1e3, {0, 0, 0}}, &original, unmoved},
                        {{"moved 1e5 + 0.37", 1, {1e5 + 0.37, 0.37, -1e5 - 0.37}}, &near, near_037}};
  for (const Case& c : cases) {
    const Move& m = c.move;
    CAPTURE(m.name);
    const fs::path dir = tmp / (std::string("case_") + std::to_string(&c - cases));
    write_moved(base, dir / "scene", m);
    const Outcome moved = train_and_export((dir / "scene").string(), dir);
    MESSAGE(std::string(m.name) << ": test PSNR " << std::setprecision(6) << moved.psnr << " dB (reference " << c.reference->psnr << "), "
                   << moved.ply.size() << " Gaussians");
    CHECK(std::isfinite(moved.psnr));
    CHECK(std::abs(moved.psnr - c.reference->psnr) <= kPsnrTolerance);

    // The PLY: its Gaussians sit where the original's sit, moved as the scene was, at its scale.
    double mean[3], log_scale = 0;
    cloud_stats(moved.ply, mean, &log_scale);
    double ref_mean[3], ref_log_scale = 0;
    cloud_stats(c.reference->ply, ref_mean, &ref_log_scale);
    const Move& r = c.reference_move;  // the reference's Gaussians back in the original frame, then moved as m
    for (int k = 0; k < 3; ++k)
      CHECK(std::abs(mean[k] - (m.scale * (ref_mean[k] - r.shift[k]) / r.scale + m.shift[k])) <= 0.02 * m.scale * extent);
    CHECK(std::abs(log_scale - (ref_log_scale + std::log(m.scale / r.scale))) <= 0.1);

    // The refined poses: each camera within a few percent of the scene's radius of its true place
    // in the user's frame (the noise was 1 % of the radius), rotation within 1.5 degrees.
    gs::Expected<gs::io::ColmapModel> moved_truth = gs::io::read_colmap_model((dir / "scene" / "sparse" / "0").string());
    REQUIRE(moved_truth.ok());
    size_t matched = 0;
    for (const gs::io::ColmapImage& r : moved.refined.images) {
      for (const gs::io::ColmapImage& t : moved_truth->images) {
        if (t.name != r.name) continue;
        double cr[3], ct[3];
        camera_centre(r, cr);
        camera_centre(t, ct);
        CHECK(std::hypot(cr[0] - ct[0], cr[1] - ct[1], cr[2] - ct[2]) <= 0.05 * m.scale * extent);
        const gs::Pose pr = gs::io::pose_from_colmap(r.qvec, r.tvec), pt = gs::io::pose_from_colmap(t.qvec, t.tvec);
        CHECK(gs::pose::rotation_error_deg(pr, pt) <= 1.5);
        ++matched;
      }
    }
    CHECK(matched == moved.refined.images.size());
    CHECK(matched > 0);
  }
  std::error_code ec;
  fs::remove_all(tmp, ec);
}
