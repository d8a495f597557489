// SPDX-License-Identifier: MIT
// Example: register images against a trained hbgs model, as a device would: everything is set up
// once (the model, the thread pool, a Registrar planned for the largest image), then each image is
// registered with a call that allocates nothing. The images here are a COLMAP dataset's views,
// each started from its recorded pose turned by DEGREES about a fixed axis through the camera
// centre; the program prints the registered pose, the verdict and the rotation error.
// Built only against the installed hbgs (find_package(hbgs) -> hbgs::hbgs, or pkg-config hbgs).
//   register_image MODEL.hbgs DATASET [DEGREES=3] [MAX_VIEWS=4] [MAX_WIDTH]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "gs/io/colmap.h"             // gs::io::load_dataset, pose_to_colmap
#include "gs/model/hybrid_model.h"    // gs::model::load_model
#include "gs/platform/thread_pool.h"  // gs::platform::ThreadPool
#include "gs/model/register.h"         // gs::pose::Registrar

namespace {

// The pose turned by `degrees` about `axis` (unit) through the camera centre: R' = D R, t' = D t.
gs::Pose turned(const gs::Pose& p, const double axis[3], double degrees) {
  const double a = degrees * M_PI / 180, c = std::cos(a), s = std::sin(a), C = 1 - c;
  const double x = axis[0], y = axis[1], z = axis[2];
  const double D[9] = {c + x * x * C,     x * y * C - z * s, x * z * C + y * s,
                       y * x * C + z * s, c + y * y * C,     y * z * C - x * s,
                       z * x * C - y * s, z * y * C + x * s, c + z * z * C};
  gs::Pose out;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j)
      out.R[i * 3 + j] = float(D[i * 3] * p.R[j] + D[i * 3 + 1] * p.R[3 + j] + D[i * 3 + 2] * p.R[6 + j]);
    out.t[i] = float(D[i * 3] * p.t[0] + D[i * 3 + 1] * p.t[1] + D[i * 3 + 2] * p.t[2]);
  }
  return out;
}

// Angle of R_a R_b^T, degrees.
double rotation_error_deg(const gs::Pose& a, const gs::Pose& b) {
  double trace = 0;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) trace += double(a.R[i * 3 + k]) * double(b.R[i * 3 + k]);
  return std::acos(std::clamp((trace - 1) / 2, -1.0, 1.0)) * 180 / M_PI;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s MODEL.hbgs DATASET [DEGREES=3] [MAX_VIEWS=4] [MAX_WIDTH]\n", argv[0]);
    return 2;
  }
  const double degrees = argc > 3 ? std::atof(argv[3]) : 3.0;
  const size_t max_views = argc > 4 ? size_t(std::max(1, std::atoi(argv[4]))) : 4;
  gs::io::DatasetOptions dataset_options;
  dataset_options.max_width = argc > 5 ? std::atoi(argv[5]) : 0;

  // Set-up: load, plan, allocate.
  gs::Expected<gs::model::HybridModel> model = gs::model::load_model(argv[1]);
  if (!model.ok()) {
    std::fprintf(stderr, "register_image: %s\n", model.status().to_string().c_str());
    return 1;
  }
  dataset_options.frame = model->frame;  // the dataset in the model's scene frame (gs/scene_frame.h)
  gs::Expected<gs::io::Dataset> dataset = gs::io::load_dataset(argv[2], dataset_options);
  if (!dataset.ok()) {
    std::fprintf(stderr, "register_image: %s\n", dataset.status().to_string().c_str());
    return 1;
  }
  const size_t n = std::min(max_views, dataset->views.size());
  int max_w = 0, max_h = 0;
  for (size_t i = 0; i < n; ++i) {
    max_w = std::max(max_w, dataset->views[i].camera.intr.width);
    max_h = std::max(max_h, dataset->views[i].camera.intr.height);
  }
  gs::platform::ThreadPool pool(0);
  gs::pose::RegisterOptions options;  // the keyframe solver, full resolution
  gs::Expected<std::unique_ptr<gs::pose::Registrar>> registrar =
      gs::pose::Registrar::create(*model, max_w, max_h, options, &pool);
  if (!registrar.ok()) {
    std::fprintf(stderr, "register_image: %s\n", registrar.status().to_string().c_str());
    return 1;
  }
  std::printf("registrar planned for %dx%d: %.1f MB\n", max_w, max_h, double((*registrar)->planned_bytes()) / 1e6);

  // Run: one allocation-free call per image.
  const double axis[3] = {0.6, 0.8, 0.0};
  int converged = 0;
  for (size_t i = 0; i < n; ++i) {
    const gs::io::DatasetView& view = dataset->views[i];
    const gs::Pose start = turned(view.camera.pose, axis, degrees);
    gs::pose::RegisterResult result;
    if (gs::Status st = (*registrar)->register_view(view.image.pixels.data(), view.camera.intr, start, &result);
        !st.ok()) {
      std::fprintf(stderr, "register_image: %s: %s\n", view.name.c_str(), st.to_string().c_str());
      return 1;
    }
    double q[4], t[3];
    gs::io::pose_to_colmap(model->frame, result.pose, q, t);  // in the dataset's own frame
    std::printf("%s: %s, pose (qw qx qy qz tx ty tz) %.5f %.5f %.5f %.5f %.4f %.4f %.4f, rotation error %.2f -> %.3f deg, "
                "RMSE %.4f -> %.4f, %d iterations, %.0f ms\n",
                view.name.c_str(), gs::pose::verdict_name(result.verdict), q[0], q[1], q[2], q[3], t[0], t[1], t[2],
                rotation_error_deg(start, view.camera.pose), rotation_error_deg(result.pose, view.camera.pose),
                result.initial_rmse, result.final_rmse, result.iterations, result.milliseconds);
    converged += result.converged() ? 1 : 0;
  }
  std::printf("%d of %zu views converged\n", converged, n);
  return 0;
}
