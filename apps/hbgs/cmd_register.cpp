// SPDX-License-Identifier: MIT
// `hbgs register`: finds the camera pose of images against a frozen trained model
// (gs::model::Registrar: photometric Levenberg-Marquardt or Adam, coarse to fine, with a verdict).
//   single image: hbgs register RUN IMAGE --init "qw qx qy qz tx ty tz" [--camera "fx fy cx cy"]
//   batch:        hbgs register RUN --views test|train|all [--init-noise rot:10,trans:0.1]
// Batch mode starts every view of the split from its dataset pose perturbed by the seeded noise
// protocol, and reports rotation and translation errors against the dataset pose, the verdicts
// and the time per view into <out>/register.json, plus the registered poses as a COLMAP model.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common.h"
#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/model/register.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose.h"
#include "gs/jobs/run_folder.h"
#include "gs/jobs/pose_truth.h"

namespace hbgs::cli {

using namespace gs::jobs;  // run folders and pose truth
namespace {

namespace fs = std::filesystem;
constexpr const char* kCmd = "register";
constexpr const char* kRegisterJson = "register.json";

struct RegisterArgs {
  std::string input, image, init, camera, json;                  // single image
  std::string views, dataset, init_noise = "rot:10,trans:0.1", out;  // batch
  std::string solver = "keyframe";
  int downscale = 1;
  int threads = 0;
  double time_budget_ms = 0;
  bool quiet = false;
};

gs::model::RegisterOptions register_options(const RegisterArgs& a) {
  gs::model::RegisterOptions o;
  o.solver = a.solver == "adam" ? gs::model::RegisterOptions::kAdam
             : a.solver == "lm"  ? gs::model::RegisterOptions::kGaussNewton
                                 : gs::model::RegisterOptions::kKeyframe;
  o.finest_downscale = a.downscale;
  o.time_budget_ms = a.time_budget_ms;
  return o;
}

// COLMAP order qw qx qy qz tx ty tz.
std::vector<double> colmap_pose(const gs::Pose& p) {
  double q[4], t[3];
  gs::io::pose_to_colmap(p, q, t);
  return {q[0], q[1], q[2], q[3], t[0], t[1], t[2]};
}

std::string pose_text(const gs::Pose& p) {
  const std::vector<double> v = colmap_pose(p);
  std::string s;
  char buf[32];
  for (size_t i = 0; i < v.size(); ++i) {
    std::snprintf(buf, sizeof(buf), i ? " %.8g" : "%.8g", v[i]);
    s += buf;
  }
  return s;
}

// Camera-centre distance of two poses, world units.
double centre_distance(const gs::Pose& a, const gs::Pose& b) {
  double ca[3], cb[3];
  gs::pose::centre(a, ca);
  gs::pose::centre(b, cb);
  return std::sqrt((ca[0] - cb[0]) * (ca[0] - cb[0]) + (ca[1] - cb[1]) * (ca[1] - cb[1]) + (ca[2] - cb[2]) * (ca[2] - cb[2]));
}

// "fx fy cx cy" (spaces and/or commas): four finite numbers, focal lengths positive.
gs::Status parse_camera(const std::string& text, gs::PinholeIntrinsics* K) {
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  std::istringstream in(s);
  std::vector<double> v;
  std::string tok;
  while (in >> tok) {
    size_t used = 0;
    double x = 0;
    try {
      x = std::stod(tok, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != tok.size() || !std::isfinite(x))
      return gs::invalid_argument("--camera: '" + tok + "' is not a finite number (expected \"fx fy cx cy\")");
    v.push_back(x);
  }
  if (v.size() != 4)
    return gs::invalid_argument("--camera: expected 4 numbers \"fx fy cx cy\", got " + std::to_string(v.size()));
  if (!(v[0] > 0) || !(v[1] > 0)) return gs::invalid_argument("--camera: fx and fy must be positive");
  K->fx = float(v[0]), K->fy = float(v[1]), K->cx = float(v[2]), K->cy = float(v[3]);
  return gs::Status::Ok();
}

// The dataset's camera for an image of width x height: the one COLMAP camera all images use
// (identical parameters), scaled when the image is a uniformly scaled version of the dataset's
// images (the rounding of the dataset loader's --max-width allowed). Otherwise an error asking
// for --camera.
gs::Status dataset_camera(const std::string& dataset, int width, int height, gs::PinholeIntrinsics* K,
                          std::string* note) {
  const std::string sparse = (fs::path(dataset) / "sparse" / "0").string();
  gs::Expected<gs::io::ColmapModel> m = gs::io::read_colmap_model(sparse);
  if (!m.ok()) return gs::invalid_argument("cannot read the dataset's camera (" + m.status().to_string() + "); pass --camera");
  const gs::io::ColmapCamera* cam = nullptr;
  for (const gs::io::ColmapImage& im : m->images) {
    const auto it = std::find_if(m->cameras.begin(), m->cameras.end(),
                                 [&](const gs::io::ColmapCamera& c) { return c.id == im.camera_id; });
    if (it == m->cameras.end()) continue;
    if (!cam) {
      cam = &*it;
    } else if (it->model != cam->model || it->width != cam->width || it->height != cam->height ||
               it->params != cam->params) {
      return gs::invalid_argument(sparse + ": the views do not share one camera (cameras " + std::to_string(cam->id) +
                                  " and " + std::to_string(it->id) + " differ); pass --camera \"fx fy cx cy\"");
    }
  }
  if (!cam) return gs::invalid_argument(sparse + ": no camera; pass --camera \"fx fy cx cy\"");
  double fx = 0, fy = 0, cx = 0, cy = 0;
  const std::vector<double>& p = cam->params;
  if ((cam->model == "PINHOLE" || cam->model == "OPENCV" || cam->model == "FULL_OPENCV") && p.size() >= 4) {
    fx = p[0], fy = p[1], cx = p[2], cy = p[3];
  } else if ((cam->model == "SIMPLE_PINHOLE" || cam->model == "SIMPLE_RADIAL" || cam->model == "RADIAL") && p.size() >= 3) {
    fx = fy = p[0], cx = p[1], cy = p[2];
  } else {
    return gs::invalid_argument(sparse + ": camera model " + cam->model + " is not supported here; pass --camera");
  }
  if (cam->model != "PINHOLE" && cam->model != "SIMPLE_PINHOLE")
    *note = "the dataset's camera is " + cam->model + " (with distortion); the image is used as a pinhole image";
  double sx = 1, sy = 1;
  if (width != cam->width || height != cam->height) {
    sx = double(width) / cam->width, sy = double(height) / cam->height;
    const long h_loader = std::max(1L, std::lround(double(cam->height) * width / cam->width));
    if (h_loader != height && std::fabs(sx / sy - 1) > 1e-3)
      return gs::invalid_argument("the image is " + std::to_string(width) + "x" + std::to_string(height) +
                                  " but the dataset's camera is " + std::to_string(cam->width) + "x" +
                                  std::to_string(cam->height) + " (not a uniform scale of it); pass --camera \"fx fy cx cy\"");
  }
  K->fx = float(fx * sx), K->cx = float(cx * sx);
  K->fy = float(fy * sy), K->cy = float(cy * sy);
  return gs::Status::Ok();
}

int run_single(const RegisterArgs& a) {
  gs::Pose init;
  if (gs::Status st = gs::pose::parse_pose(a.init, "--init", &init); !st.ok()) return fail(kCmd, st.message());
  gs::PinholeIntrinsics K;
  if (!a.camera.empty())
    if (gs::Status st = parse_camera(a.camera, &K); !st.ok()) return fail(kCmd, st.message());
  if (!gs::platform::file_exists(a.image)) return fail(kCmd, "image " + a.image + " not found");

  // The model (and, without --camera, the dataset whose camera took the image).
  ModelSource src;
  gs::Expected<ModelSource> resolved = resolve_model_source(a.input, a.dataset, -1);
  if (resolved.ok()) {
    src = *resolved;
  } else if (!a.camera.empty()) {
    src.model_path = gs::platform::is_directory(a.input) ? (fs::path(a.input) / kModelFile).string() : a.input;
  } else {
    return fail(kCmd, resolved.status().to_string() + " (or pass --camera \"fx fy cx cy\")");
  }
  gs::Expected<gs::model::HybridModel> model = gs::model::load_model(src.model_path);
  if (!model.ok()) return fail(kCmd, model.status().to_string());
  gs::Expected<gs::io::Image8> img = gs::io::read_image(a.image, 3);
  if (!img.ok()) return fail(kCmd, img.status().to_string());
  K.width = img->width;
  K.height = img->height;
  std::string note;
  if (a.camera.empty())
    if (gs::Status st = dataset_camera(src.dataset, img->width, img->height, &K, &note); !st.ok())
      return fail(kCmd, a.image + ": " + st.message());
  if (!note.empty() && !a.quiet) std::fprintf(stderr, "note: %s\n", note.c_str());

  gs::platform::ThreadPool pool(a.threads);
  gs::Expected<std::unique_ptr<gs::model::Registrar>> reg =
      gs::model::Registrar::create(*model, img->width, img->height, register_options(a), &pool);
  if (!reg.ok()) return fail(kCmd, reg.status().to_string());
  gs::model::RegisterResult r;
  if (gs::Status st = (*reg)->register_view(img->pixels.data(), K, init, &r); !st.ok())
    return fail(kCmd, a.image + ": " + st.to_string());

  const double moved_deg = gs::pose::rotation_error_deg(r.pose, init), moved = centre_distance(r.pose, init);
  nlohmann::ordered_json j = {{"model", absolute_path(src.model_path)},
                      {"image", absolute_path(a.image)},
                      {"intrinsics", {{"fx", K.fx}, {"fy", K.fy}, {"cx", K.cx}, {"cy", K.cy}, {"width", K.width}, {"height", K.height}}},
                      {"solver", a.solver},
                      {"downscale", a.downscale},
                      {"threads", pool.num_threads()},
                      {"pose_order", "qw qx qy qz tx ty tz (world-to-camera, COLMAP)"},
                      {"init", colmap_pose(init)},
                      {"pose", colmap_pose(r.pose)},
                      {"verdict", gs::model::verdict_name(r.verdict)},
                      {"converged", r.converged()},
                      {"initial_rmse", r.initial_rmse},
                      {"final_rmse", r.final_rmse},
                      {"coverage", r.coverage},
                      {"explained", r.explained},
                      {"moved_rotation_deg", moved_deg},
                      {"moved_translation", moved},
                      {"iterations", r.iterations},
                      {"levels", r.levels},
                      {"ms", r.milliseconds}};
  if (!a.json.empty())
    if (gs::Status st = gs::platform::write_file_atomic(a.json, j.dump(2) + "\n"); !st.ok()) return fail(kCmd, st.to_string());

  std::printf("hbgs register: %s (%dx%d) against %s\n", a.image.c_str(), img->width, img->height, src.model_path.c_str());
  std::printf("  pose (qw qx qy qz tx ty tz): %s\n", pose_text(r.pose).c_str());
  std::printf("  verdict %s; RMSE %.4f -> %.4f, explained %.2f, coverage %.2f\n", gs::model::verdict_name(r.verdict),
              r.initial_rmse, r.final_rmse, r.explained, r.coverage);
  std::printf("  moved %.3f deg, %.4g from --init; %d iterations over %d levels, %.1f ms (%s, downscale %d, %d threads)\n",
              moved_deg, moved, r.iterations, r.levels, r.milliseconds, a.solver.c_str(), a.downscale, pool.num_threads());
  if (!a.json.empty()) std::printf("  json: %s\n", a.json.c_str());
  return kExitOk;
}

struct ViewRow {
  std::string name;
  double init_rot = 0, init_trans = 0, rot = 0, trans = 0;
  bool success = false;
  gs::model::RegisterResult r;
};

int run_batch(const RegisterArgs& a) {
  if (!gs::platform::file_exists(a.input)) return fail(kCmd, a.input + " not found");
  if (!is_model_input(a.input))
    return fail(kCmd, a.input + " is neither a run folder (with run.json or model.hbgs) nor a .hbgs model file");
  gs::pose::PoseNoise noise;
  if (gs::Status st = gs::pose::parse_pose_noise(a.init_noise, &noise); !st.ok())
    return fail(kCmd, "--init-noise: " + st.message());
  gs::Expected<ModelSource> src = resolve_model_source(a.input, a.dataset, -1);
  if (!src.ok()) return fail(kCmd, src.status().to_string());
  gs::Expected<gs::model::HybridModel> model = gs::model::load_model(src->model_path);
  if (!model.ok()) return fail(kCmd, model.status().to_string());
  gs::Expected<std::unique_ptr<LoadedDataset>> data = load_dataset_split(src->dataset, src->max_width, a.views);
  if (!data.ok()) return fail(kCmd, data.status().to_string());
  gs::io::Dataset& ds = (*data)->dataset;
  // True poses and the scene frame of the training cameras; the start poses are the perturbed ones.
  PoseTruth truth;
  if (gs::Status st = apply_pose_noise(&ds, a.init_noise, a.views, &truth); !st.ok())
    return fail(kCmd, "--init-noise: " + st.message());
  const std::string out = a.out.empty() ? (fs::path(src->run_dir) / "register").string() : a.out;
  if (gs::platform::file_exists(out) && !gs::platform::is_directory(out))
    return fail(kCmd, "output " + out + " exists and is not a directory");

  std::vector<size_t> index;  // dataset indices of the split, in name order (the dataset is sorted)
  int max_w = 0, max_h = 0;
  for (size_t i = 0; i < ds.views.size(); ++i) {
    const gs::io::DatasetView& v = ds.views[i];
    if (!(a.views == "all" || (a.views == "test") == v.is_test)) continue;
    index.push_back(i);
    max_w = std::max(max_w, v.camera.intr.width);
    max_h = std::max(max_h, v.camera.intr.height);
  }

  // One registrar for every view: planned once, then allocation-free.
  gs::platform::ThreadPool pool(a.threads);
  gs::Expected<std::unique_ptr<gs::model::Registrar>> reg =
      gs::model::Registrar::create(*model, max_w, max_h, register_options(a), &pool);
  if (!reg.ok()) return fail(kCmd, reg.status().to_string());

  Stopwatch total;
  const double radius = truth.radius;
  std::vector<ViewRow> rows;
  std::vector<gs::Pose> estimated;
  std::vector<std::string> names;
  for (size_t k = 0; k < index.size(); ++k) {
    const gs::io::DatasetView& v = ds.views[index[k]];
    const gs::Pose& gt = truth.poses[index[k]];
    ViewRow row;
    row.name = v.name;
    row.init_rot = gs::pose::rotation_error_deg(v.camera.pose, gt);
    row.init_trans = centre_distance(v.camera.pose, gt);
    if (gs::Status st = (*reg)->register_view(v.image.pixels.data(), v.camera.intr, v.camera.pose, &row.r); !st.ok())
      return fail(kCmd, "view " + v.name + ": " + st.to_string());
    row.rot = gs::pose::rotation_error_deg(row.r.pose, gt);
    row.trans = centre_distance(row.r.pose, gt);
    row.success = row.rot < 1.0 && row.trans < 0.01 * radius;
    if (!a.quiet)
      std::fprintf(stderr, "[%zu/%zu] %s: rotation %.2f -> %.3f deg, translation %.3f -> %.4f r, %s, %d it, %.0f ms\n",
                   k + 1, index.size(), v.name.c_str(), row.init_rot, row.rot, row.init_trans / radius,
                   row.trans / radius, gs::model::verdict_name(row.r.verdict), row.r.iterations, row.r.milliseconds);
    estimated.push_back(row.r.pose);
    names.push_back(v.name);
    rows.push_back(std::move(row));
  }

  // Image metrics of the split at the start poses and at the registered poses (the paper registers
  // test views before measuring; both are reported, named as what they are).
  std::vector<gs::io::DatasetView> at_start, at_registered;
  for (size_t k = 0; k < index.size(); ++k) {
    at_start.push_back(ds.views[index[k]]);
    at_registered.push_back(ds.views[index[k]]);
    at_registered.back().camera.pose = estimated[k];
  }
  auto metrics = [&](const std::vector<gs::io::DatasetView>& views) -> gs::Expected<gs::model::EvalResult> {
    std::vector<const gs::io::DatasetView*> ptrs;
    for (const gs::io::DatasetView& v : views) ptrs.push_back(&v);
    return gs::model::evaluate_views(*model, ptrs, gs::model::EvalOptions{}, &pool);
  };
  gs::Expected<gs::model::EvalResult> m_start = metrics(at_start), m_reg = metrics(at_registered);
  if (!m_start.ok()) return fail(kCmd, m_start.status().to_string());
  if (!m_reg.ok()) return fail(kCmd, m_reg.status().to_string());

  std::vector<double> rot, trans, init_rot, init_trans, ms;
  size_t success = 0, converged = 0;
  nlohmann::ordered_json jv = nlohmann::ordered_json::array();
  for (const ViewRow& row : rows) {
    rot.push_back(row.rot);
    trans.push_back(row.trans);
    init_rot.push_back(row.init_rot);
    init_trans.push_back(row.init_trans);
    ms.push_back(row.r.milliseconds);
    success += row.success;
    converged += row.r.converged();
    jv.push_back({{"name", row.name},
                  {"initial_rotation_deg", row.init_rot},
                  {"initial_translation", row.init_trans},
                  {"initial_translation_fraction", row.init_trans / radius},
                  {"rotation_deg", row.rot},
                  {"translation", row.trans},
                  {"translation_fraction", row.trans / radius},
                  {"success", row.success},
                  {"verdict", gs::model::verdict_name(row.r.verdict)},
                  {"initial_rmse", row.r.initial_rmse},
                  {"final_rmse", row.r.final_rmse},
                  {"explained", row.r.explained},
                  {"coverage", row.r.coverage},
                  {"iterations", row.r.iterations},
                  {"levels", row.r.levels},
                  {"ms", row.r.milliseconds},
                  {"pose", colmap_pose(row.r.pose)}});
  }
  const double n = double(rows.size());
  nlohmann::ordered_json summary = {{"views", rows.size()},
                            {"median_initial_rotation_deg", gs::median(init_rot)},
                            {"median_initial_translation", gs::median(init_trans)},
                            {"median_rotation_deg", gs::median(rot)},
                            {"mean_rotation_deg", mean_of(rot)},
                            {"median_translation", gs::median(trans)},
                            {"median_translation_fraction", gs::median(trans) / radius},
                            {"success_rate", double(success) / n},
                            {"converged_rate", double(converged) / n},
                            {"psnr_at_start_poses", m_start->psnr},
                            {"ssim_at_start_poses", m_start->ssim},
                            {"psnr_registered", m_reg->psnr},
                            {"ssim_registered", m_reg->ssim},
                            {"median_ms", gs::median(ms)},
                            {"mean_ms", mean_of(ms)},
                            {"total_seconds", total.seconds()}};
  nlohmann::ordered_json j = {{"model", absolute_path(src->model_path)},
                      {"dataset", absolute_path(src->dataset)},
                      {"max_width", src->max_width},
                      {"split", a.views},
                      {"init_noise", gs::pose::describe(noise)},
                      {"solver", a.solver},
                      {"downscale", a.downscale},
                      {"time_budget_ms", a.time_budget_ms},
                      {"threads", pool.num_threads()},
                      {"anchors", model->anchor_count},
                      {"scene_radius", radius},
                      {"scene_radius_definition", "largest distance of a training camera centre from their mean"},
                      {"translation_definition", "camera-centre distance to the dataset pose, scene units (no alignment)"},
                      {"success_definition", "rotation error < 1 deg and translation error < 0.01 scene radius"},
                      {"pose_order", "qw qx qy qz tx ty tz (world-to-camera, COLMAP)"},
                      {"summary", summary},
                      {"views", std::move(jv)}};
  if (gs::Status st = gs::platform::make_dirs(out); !st.ok()) return fail(kCmd, st.to_string());
  const std::string json_path = (fs::path(out) / kRegisterJson).string();
  const std::string text = j.dump(2) + "\n";
  if (gs::Status st = gs::platform::write_file_atomic(json_path, text); !st.ok()) return fail(kCmd, st.to_string());
  if (!a.json.empty())
    if (gs::Status st = gs::platform::write_file_atomic(a.json, text); !st.ok()) return fail(kCmd, st.to_string());
  const std::string posed = (fs::path(out) / "registered").string();
  if (gs::Status st = write_posed_model(src->dataset, names, estimated, posed); !st.ok())
    return fail(kCmd, st.to_string());

  std::printf("hbgs register: %zu %s views of %s against %s (%s, downscale %d, %d threads)\n", rows.size(),
              a.views.c_str(), src->dataset.c_str(), src->model_path.c_str(), a.solver.c_str(), a.downscale,
              pool.num_threads());
  std::printf("  start: %s (median %.2f deg, %.3f of the scene radius %.4g)\n", gs::pose::describe(noise).c_str(),
              gs::median(init_rot), gs::median(init_trans) / radius, radius);
  std::printf("  final: median rotation %.4f deg, median translation %.4g (%.5f of the radius)\n", gs::median(rot),
              gs::median(trans), gs::median(trans) / radius);
  std::printf("  success (< 1 deg and < 1%% of the radius) %zu/%zu, converged verdict %zu/%zu\n", success, rows.size(),
              converged, rows.size());
  std::printf("  time per view: median %.1f ms, mean %.1f ms (total %.1f s)\n", gs::median(ms), mean_of(ms),
              total.seconds());
  std::printf("  images: PSNR %.2f dB / SSIM %.4f at the start poses, %.2f dB / %.4f at the registered poses\n",
              m_start->psnr, m_start->ssim, m_reg->psnr, m_reg->ssim);
  std::printf("  results: %s, poses: %s/\n", json_path.c_str(), posed.c_str());
  return kExitOk;
}

int run_register(const RegisterArgs& a) {
  if (!a.image.empty()) {
    if (!a.views.empty()) {
      fail(kCmd, "give either an IMAGE (with --init) or --views, not both");
      return kExitUsage;
    }
    if (a.init.empty()) {
      fail(kCmd, "an IMAGE needs its start pose: --init \"qw qx qy qz tx ty tz\"");
      return kExitUsage;
    }
    return run_single(a);
  }
  if (a.views.empty()) {
    fail(kCmd, "give an IMAGE with --init \"qw qx qy qz tx ty tz\", or --views test|train|all");
    return kExitUsage;
  }
  if (!a.init.empty() || !a.camera.empty()) {
    fail(kCmd, "--init and --camera apply to a single IMAGE; --views starts from the dataset poses (--init-noise)");
    return kExitUsage;
  }
  return run_batch(a);
}

}  // namespace

Command add_register_command(CLI::App& parent) {
  auto args = std::make_shared<RegisterArgs>();
  CLI::App* sub = parent.add_subcommand(
      "register", "Find the camera pose of an image (or of a dataset's views) against a trained model");
  sub->add_option("model", args->input, "Run folder (from hbgs train) or .hbgs model file")->required();
  sub->add_option("image", args->image, "Image to register (single-image mode; needs --init)");
  sub->add_option("--init", args->init, "Start pose \"qw qx qy qz tx ty tz\" (world-to-camera, COLMAP order)");
  sub->add_option("--camera", args->camera,
                  "Intrinsics \"fx fy cx cy\" in pixels of IMAGE (default: the dataset's camera, scaled to the image)");
  sub->add_option("--json", args->json, "Also write the result as JSON to this file");
  sub->add_option("--views", args->views, "Batch mode: register these views of the dataset from perturbed poses")
      ->check(CLI::IsMember({"test", "train", "all"}));
  sub->add_option("--dataset", args->dataset, "COLMAP dataset (default: the one recorded in the run's run.json)");
  sub->add_option("--init-noise", args->init_noise,
                  "Batch mode: start-pose noise, rot:DEG,trans:FRACTION_OF_RADIUS[,seed:N] or barf:SIGMA")
      ->capture_default_str();
  sub->add_option("--out", args->out, "Batch mode: folder for register.json and registered/ (default: <run>/register)");
  sub->add_option("--downscale", args->downscale, "Resolution divisor of the finest level (4: quarter resolution)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  sub->add_option("--solver", args->solver, "keyframe (direct alignment to rendered keyframes, then LM polish), lm (Levenberg-Marquardt with the renderer's analytic pose Jacobian at every level) or adam")
      ->capture_default_str()
      ->check(CLI::IsMember({"keyframe", "lm", "adam"}));
  sub->add_option("--time-budget-ms", args->time_budget_ms, "Stop a view after this many ms, keeping the best pose (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e9));
  sub->add_option("--threads", args->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_flag("-q,--quiet", args->quiet, "No per-view progress lines");
  return {sub, [args] { return run_register(*args); }};
}

}  // namespace hbgs::cli
