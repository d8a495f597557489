// SPDX-License-Identifier: MIT
// The registration jobs (gs/jobs/register.h): one image, or a dataset split from perturbed starts.
#include "gs/jobs/register.h"

#include "gs/io/composite.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/io/splat_formats.h"
#include "gs/jobs/pose_truth.h"
#include "gs/model/evaluate.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/trainer.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/stats.h"
#include "camera_input.h"

namespace gs::jobs {
namespace {

namespace fs = std::filesystem;
constexpr const char* kRegisterJson = "register.json";

// COLMAP order qw qx qy qz tx ty tz, in the user's frame (a pose in the model's scene frame).
std::vector<double> colmap_pose(const SceneFrame& frame, const Pose& p) {
  double q[4], t[3];
  io::pose_to_colmap(frame, p, q, t);
  return {q[0], q[1], q[2], q[3], t[0], t[1], t[2]};
}

// Camera-centre distance of two poses, world units.
double centre_distance(const Pose& a, const Pose& b) {
  double ca[3], cb[3];
  pose::centre(a, ca);
  pose::centre(b, cb);
  return std::sqrt((ca[0] - cb[0]) * (ca[0] - cb[0]) + (ca[1] - cb[1]) * (ca[1] - cb[1]) + (ca[2] - cb[2]) * (ca[2] - cb[2]));
}

// The dataset's camera for an image of width x height: the one camera all its views use (identical
// parameters; a COLMAP or NeRF-style dataset, io::read_dataset_files), scaled when the image is a
// uniformly scaled version of the dataset's images (the rounding of the dataset loader's
// --max-width allowed). Otherwise an error asking for --camera.
Status dataset_camera(const std::string& dataset, int width, int height, PinholeIntrinsics* K, std::string* note) {
  Expected<io::DatasetFiles> files = io::read_dataset_files(dataset);
  if (!files.ok()) return invalid_argument("cannot read the dataset's camera (" + files.status().to_string() + "); pass --camera");
  io::ColmapCamera cam;
  GS_RETURN_IF_ERROR(shared_dataset_camera(*files, dataset, "pass --camera \"fx fy cx cy\"", &cam, note));
  if (!is_uniform_scale(cam, width, height))
    return invalid_argument("the image is " + std::to_string(width) + "x" + std::to_string(height) +
                            " but the dataset's camera is " + std::to_string(cam.width) + "x" + std::to_string(cam.height) +
                            " (not a uniform scale of it); pass --camera \"fx fy cx cy\"");
  const PinholeIntrinsics scaled = scaled_intrinsics(cam, width, height);
  K->fx = scaled.fx, K->fy = scaled.fy, K->cx = scaled.cx, K->cy = scaled.cy;
  return Status::Ok();
}

// The size of a scene given only as Gaussians: 1.1 x the 90th percentile of the means' distances
// from their median (robust to the far background Gaussians trained scenes often hold).
float cloud_extent(const GaussianCloud& c) {
  const size_t n = c.size();
  double med[3];
  std::vector<double> v(n);
  for (int k = 0; k < 3; ++k) {
    for (size_t i = 0; i < n; ++i) v[i] = c.means[3 * i + size_t(k)];
    std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(n / 2), v.end());
    med[k] = v[n / 2];
  }
  for (size_t i = 0; i < n; ++i) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 += (c.means[3 * i + size_t(k)] - med[k]) * (c.means[3 * i + size_t(k)] - med[k]);
    v[i] = std::sqrt(d2);
  }
  const size_t p90 = std::min(n - 1, n * 9 / 10);
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(p90), v.end());
  return float(1.1 * std::max(v[p90], 1e-6));
}

// The image to register as RGB: an alpha channel (RGBA PNG) composites it on the background the
// model renders on, as training composites masked views.
Expected<io::Image8> read_composited(const std::string& path, const float background[3]) {
  Expected<io::Image8> rgba = io::read_image(path, 4);
  if (!rgba.ok()) return rgba.status();
  io::Image8 rgb, alpha;
  rgb.width = alpha.width = rgba->width;
  rgb.height = alpha.height = rgba->height;
  rgb.channels = 3;
  alpha.channels = 1;
  const size_t n = size_t(rgba->width) * size_t(rgba->height);
  rgb.pixels.resize(3 * n);
  alpha.pixels.resize(n);
  bool opaque = true;
  for (size_t p = 0; p < n; ++p) {
    for (int c = 0; c < 3; ++c) rgb.pixels[3 * p + size_t(c)] = rgba->pixels[4 * p + size_t(c)];
    alpha.pixels[p] = rgba->pixels[4 * p + 3];
    opaque = opaque && alpha.pixels[p] == 255;
  }
  return opaque ? rgb : io::composite_rgb8(rgb, alpha, background);
}

}  // namespace

Expected<pose::RegisterOptions> register_options(const RegisterRunOptions& a) {
  pose::RegisterOptions o;
  if (a.solver == "adam") o.solver = pose::RegisterOptions::kAdam;
  else if (a.solver == "lm") o.solver = pose::RegisterOptions::kGaussNewton;
  else if (a.solver == "keyframe") o.solver = pose::RegisterOptions::kKeyframe;
  else return invalid_argument("--solver: '" + a.solver + "' is not one of keyframe, lm, adam");
  if (a.downscale < 1) return invalid_argument("--downscale must be at least 1");
  if (!(a.time_budget_ms >= 0)) return invalid_argument("--time-budget-ms must be 0 or positive");
  o.finest_downscale = a.downscale;
  o.time_budget_ms = a.time_budget_ms;
  o.fixed_point = a.fixed_point;
  if (a.relocalize < 0) return invalid_argument("--relocalize must be 0 or positive");
  o.relocalize_candidates = a.relocalize;
  return o;
}

Status register_image(const RegisterRunOptions& a, RegisterImageSummary* summary) {
  RegisterImageSummary s;
  Expected<pose::RegisterOptions> ro = register_options(a);
  if (!ro.ok()) return ro.status();
  if (a.image.empty()) return invalid_argument("no image to register");
  GS_RETURN_IF_ERROR(pose::parse_pose(a.init, "--init", &s.init));
  PinholeIntrinsics& K = s.intrinsics;
  if (!a.camera.empty()) GS_RETURN_IF_ERROR(parse_intrinsics_text(a.camera, "--camera", &K));
  if (!platform::file_exists(a.image)) return invalid_argument("image " + a.image + " not found");

  // The model (and, without a camera, the dataset whose camera took the image).
  Expected<ModelSource> resolved = resolve_model_source(a.input, a.dataset, -1);
  if (resolved.ok()) {
    s.source = *resolved;
  } else if (!a.camera.empty()) {
    s.source.model_path = platform::is_directory(a.input) ? (fs::path(a.input) / kModelFile).string() : a.input;
  } else {
    return Status(resolved.status().code(), resolved.status().message() + " (or pass --camera \"fx fy cx cy\")");
  }
  Expected<model::Background> background = model_background(s.source, a.background);
  if (!background.ok()) return background.status();
  std::copy(background->rgb, background->rgb + 3, ro->background);
  // The model: an anchor model, or plain Gaussians from a splat file (whose world size comes from
  // the dataset's training cameras when there is a dataset, else from the Gaussians themselves).
  model::HybridModel model;
  GaussianCloud cloud;
  float extent = 0;
  const bool is_cloud = is_splat_file(s.source.model_path);
  if (is_cloud) {
    Expected<GaussianCloud> c = io::read_gaussians(s.source.model_path);
    if (!c.ok()) return c.status();
    if (c->size() == 0) return invalid_argument(s.source.model_path + ": holds no Gaussians");
    cloud = std::move(c).value();
    extent = cloud_extent(cloud);
    if (!s.source.dataset.empty()) {
      io::DatasetOptions dopt;
      dopt.images = io::DatasetOptions::Images::kTest;  // cameras only for the training views
      Expected<io::Dataset> ds = io::load_dataset(s.source.dataset, dopt);
      if (!ds.ok()) return ds.status();
      s.frame = ds->frame;  // the Gaussians move into the dataset's scene frame
      cloud_to_frame(s.frame, &cloud);
      std::vector<const Camera*> train;
      for (const io::DatasetView& v : ds->views)
        if (!v.is_test) train.push_back(&v.camera);
      if (!train.empty()) extent = model::cameras_extent(train);
    }
  } else {
    Expected<model::HybridModel> m = model::load_model(s.source.model_path);
    if (!m.ok()) return m.status();
    model = std::move(m).value();
    extent = model.scene_extent;
    s.frame = model.frame;
  }
  // The start pose is in the user's frame, read again in double (parse_pose checked it): far
  // from the origin float would have lost its translation.
  if (!s.frame.identity()) {
    double q[4], t[3], R[9];
    pose_text_numbers(a.init, q, t);
    pose::rotation_from_quaternion(q, R);
    s.init = pose_to_frame(s.frame, R, t);
  }
  // A start pose far outside the scene cannot be registered (the model is not in view, and float
  // rendering loses all precision at 1e30): refuse it with the distance instead of failing later.
  {
    double C[3], mean[3] = {0, 0, 0};
    pose::centre(s.init, C);
    const size_t M = is_cloud ? cloud.size() : model.anchor_count;
    const float* positions = is_cloud ? cloud.means.data() : model.positions.data();
    for (size_t i = 0; i < M; ++i)
      for (int k = 0; k < 3; ++k) mean[k] += double(positions[3 * i + size_t(k)]) / double(M);
    const double d = std::sqrt((C[0] - mean[0]) * (C[0] - mean[0]) + (C[1] - mean[1]) * (C[1] - mean[1]) +
                               (C[2] - mean[2]) * (C[2] - mean[2]));
    const double limit = kMaxStartDistanceInRadii * double(extent);
    auto g = [](double v) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%.4g", v);
      return std::string(buf);
    };
    if (!(d <= limit))
      return invalid_argument("--init: the camera centre is " + g(d) + " from the scene's centre, more than " +
                              g(kMaxStartDistanceInRadii) + " times the scene radius " + g(extent) +
                              "; check the pose's order (qw qx qy qz tx ty tz, world-to-camera as in COLMAP) and units");
  }
  Expected<io::Image8> img = read_composited(a.image, background->rgb);
  if (!img.ok()) return img.status();
  K.width = img->width;
  K.height = img->height;
  if (a.camera.empty())
    if (Status st = dataset_camera(s.source.dataset, img->width, img->height, &K, &s.note); !st.ok())
      return Status(st.code(), a.image + ": " + st.message());

  platform::ThreadPool pool(a.threads);
  s.threads = pool.num_threads();
  Expected<std::unique_ptr<pose::Registrar>> reg =
      is_cloud ? pose::Registrar::create(cloud, extent, img->width, img->height, *ro, &pool)
               : pose::Registrar::create(model, img->width, img->height, *ro, &pool);
  if (!reg.ok()) return reg.status();
  pose::RegisterResult& r = s.result;
  if (Status st = (*reg)->register_view(img->pixels.data(), K, s.init, &r); !st.ok())
    return Status(st.code(), a.image + ": " + st.message());

  s.moved_rotation_deg = pose::rotation_error_deg(r.pose, s.init);
  s.moved_translation = centre_distance(r.pose, s.init) / s.frame.scale;
  io::pose_to_colmap(s.frame, r.pose, s.pose_qvec, s.pose_tvec);
  nlohmann::ordered_json j = {{"model", absolute_path(s.source.model_path)},
                              {"image", absolute_path(a.image)},
                              {"intrinsics", {{"fx", K.fx}, {"fy", K.fy}, {"cx", K.cx}, {"cy", K.cy}, {"width", K.width}, {"height", K.height}}},
                              {"solver", a.solver},
                              {"downscale", a.downscale},
                              {"threads", s.threads},
                              {"pose_order", "qw qx qy qz tx ty tz (world-to-camera, COLMAP)"},
                              {"init", colmap_pose(s.frame, s.init)},
                              {"pose", colmap_pose(s.frame, r.pose)},
                              {"verdict", pose::verdict_name(r.verdict)},
                              {"converged", r.converged()},
                              {"initial_rmse", r.initial_rmse},
                              {"final_rmse", r.final_rmse},
                              {"coverage", r.coverage},
                              {"explained", r.explained},
                              {"moved_rotation_deg", s.moved_rotation_deg},
                              {"moved_translation", s.moved_translation},
                              {"iterations", r.iterations},
                              {"levels", r.levels},
                              {"ms", r.milliseconds}};
  if (!a.json.empty()) GS_RETURN_IF_ERROR(platform::write_file_atomic(a.json, j.dump(2) + "\n"));
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

namespace {

// Registers each view of the split (dataset indices `index`) from its start pose against its true
// pose; rows[k] and estimated[k] belong to ds.views[index[k]]; candidates[c] is the dataset index
// of the registrar's relocalisation candidate c.
Status register_split(pose::Registrar& reg, const io::Dataset& ds, const std::vector<size_t>& index, const PoseTruth& truth,
                      const std::vector<size_t>& candidates, const float background[3],
                      const std::function<void(const RegisteredView&, size_t, size_t)>& progress,
                      std::vector<RegisteredView>* rows, std::vector<Pose>* estimated) {
  const double radius = truth.radius * truth.unit;  // user units, as the distances below
  for (size_t k = 0; k < index.size(); ++k) {
    const io::DatasetView& v = ds.views[index[k]];
    const Pose& gt = truth.poses[index[k]];
    RegisteredView row;
    row.name = v.name;
    row.initial_rotation_deg = pose::rotation_error_deg(v.camera.pose, gt);
    row.initial_translation = centre_distance(v.camera.pose, gt) * truth.unit;
    const io::Image8 photo = io::composite_rgb8(v.image, v.mask, background);  // a copy only when masked
    if (Status st = reg.register_view(photo.pixels.data(), v.camera.intr, v.camera.pose, &row.result); !st.ok())
      return Status(st.code(), "view " + v.name + ": " + st.message());
    if (row.result.relocalized_from >= 0) row.relocalized_from = ds.views[candidates[size_t(row.result.relocalized_from)]].name;
    row.rotation_deg = pose::rotation_error_deg(row.result.pose, gt);
    row.translation = centre_distance(row.result.pose, gt) * truth.unit;
    row.success = row.rotation_deg < 1.0 && row.translation < 0.01 * radius;
    row.initial_translation_fraction = row.initial_translation / radius;
    row.translation_fraction = row.translation / radius;
    estimated->push_back(row.result.pose);
    rows->push_back(std::move(row));
    if (progress) progress(rows->back(), k + 1, index.size());
  }
  return Status::Ok();
}

// Image metrics of the split at the start poses and at the registered poses (the paper registers
// test views before measuring; both are reported, named as what they are). The split's views hold
// the start poses; they are measured, then given the registered poses in place and measured again
// (no copies of the images).
Status evaluate_split(const ModelViews& loaded, io::Dataset& ds, const std::vector<size_t>& index,
                      const std::vector<Pose>& estimated, const model::EvalOptions& eo, platform::ThreadPool* pool,
                      model::EvalResult* at_start, model::EvalResult* registered) {
  std::vector<const io::DatasetView*> split_views;
  for (size_t k = 0; k < index.size(); ++k) split_views.push_back(&ds.views[index[k]]);
  Expected<model::EvalResult> m_start = evaluate_loaded(loaded, split_views, eo, pool);
  if (!m_start.ok()) return m_start.status();
  for (size_t k = 0; k < index.size(); ++k) ds.views[index[k]].camera.pose = estimated[k];
  Expected<model::EvalResult> m_reg = evaluate_loaded(loaded, split_views, eo, pool);
  if (!m_reg.ok()) return m_reg.status();
  *at_start = std::move(m_start).value();
  *registered = std::move(m_reg).value();
  return Status::Ok();
}

// The split's figures over its rows.
struct SplitFigures {
  std::vector<double> rot, trans, init_rot, init_trans, ms;
  size_t success = 0, converged = 0, relocalized = 0;
};
SplitFigures split_figures(const std::vector<RegisteredView>& rows) {
  SplitFigures f;
  for (const RegisteredView& row : rows) {
    f.rot.push_back(row.rotation_deg);
    f.trans.push_back(row.translation);
    f.init_rot.push_back(row.initial_rotation_deg);
    f.init_trans.push_back(row.initial_translation);
    f.ms.push_back(row.result.milliseconds);
    f.success += row.success;
    f.converged += row.result.converged();
    f.relocalized += !row.relocalized_from.empty();
  }
  return f;
}

nlohmann::ordered_json registered_views_json(const std::vector<RegisteredView>& rows, double radius, const SceneFrame& frame) {
  nlohmann::ordered_json jv = nlohmann::ordered_json::array();
  for (const RegisteredView& row : rows)
    jv.push_back({{"name", row.name},
                  {"initial_rotation_deg", row.initial_rotation_deg},
                  {"initial_translation", row.initial_translation},
                  {"initial_translation_fraction", row.initial_translation / radius},
                  {"rotation_deg", row.rotation_deg},
                  {"translation", row.translation},
                  {"translation_fraction", row.translation / radius},
                  {"success", row.success},
                  {"verdict", pose::verdict_name(row.result.verdict)},
                  {"relocalized_from", row.relocalized_from.empty() ? nlohmann::ordered_json() : nlohmann::ordered_json(row.relocalized_from)},
                  {"relocalize_attempts", row.result.relocalize_attempts},
                  {"initial_rmse", row.result.initial_rmse},
                  {"final_rmse", row.result.final_rmse},
                  {"explained", row.result.explained},
                  {"coverage", row.result.coverage},
                  {"iterations", row.result.iterations},
                  {"levels", row.result.levels},
                  {"ms", row.result.milliseconds},
                  {"pose", colmap_pose(frame, row.result.pose)}});
  return jv;
}

// register.json: the run's set-up, the summary and every view.
nlohmann::ordered_json register_views_json(const RegisterRunOptions& a, const ModelViews& loaded, const std::string& noise,
                                           int threads, double radius, const std::vector<RegisteredView>& rows,
                                           const SplitFigures& f, const model::EvalResult& m_start,
                                           const model::EvalResult& m_reg, double seconds, size_t candidates) {
  const double n = double(rows.size());
  nlohmann::ordered_json jsum = {{"views", rows.size()},
                                 {"median_initial_rotation_deg", median(f.init_rot)},
                                 {"median_initial_translation", median(f.init_trans)},
                                 {"median_rotation_deg", median(f.rot)},
                                 {"mean_rotation_deg", mean(f.rot)},
                                 {"median_translation", median(f.trans)},
                                 {"median_translation_fraction", median(f.trans) / radius},
                                 {"success_rate", double(f.success) / n},
                                 {"converged_rate", double(f.converged) / n},
                                 {"relocalized", f.relocalized},
                                 {"psnr_at_start_poses", m_start.psnr},
                                 {"ssim_at_start_poses", m_start.ssim},
                                 {"psnr_registered", m_reg.psnr},
                                 {"ssim_registered", m_reg.ssim},
                                 {"median_ms", median(f.ms)},
                                 {"mean_ms", mean(f.ms)},
                                 {"total_seconds", seconds}};
  return {{"model", absolute_path(loaded.source.model_path)},
          {"dataset", absolute_path(loaded.source.dataset)},
          {"max_width", loaded.source.max_width},
          {"split", a.views},
          {"init_noise", noise},
          {"solver", a.solver},
          {"downscale", a.downscale},
          {"time_budget_ms", a.time_budget_ms},
          {"relocalize", a.relocalize},
          {"relocalize_candidates", candidates},
          {"threads", threads},
          {"anchors", loaded.model.anchor_count},
          {"scene_radius", radius},
          {"scene_radius_definition", "largest distance of a training camera centre from their mean"},
          {"translation_definition", "camera-centre distance to the dataset pose, scene units (no alignment)"},
          {"success_definition", "rotation error < 1 deg and translation error < 0.01 scene radius"},
          {"pose_order", "qw qx qy qz tx ty tz (world-to-camera, COLMAP)"},
          {"summary", jsum},
          {"views", registered_views_json(rows, radius, loaded.frame())}};
}

}  // namespace

Status register_views(const RegisterRunOptions& a, const std::function<void(const RegisteredView&, size_t, size_t)>& progress,
                      RegisterViewsSummary* summary) {
  Expected<pose::RegisterOptions> ro = register_options(a);
  if (!ro.ok()) return ro.status();
  if (a.views != "test" && a.views != "train" && a.views != "all")
    return invalid_argument("--views: '" + a.views + "' is not one of test, train, all");
  if (!platform::file_exists(a.input)) return invalid_argument(a.input + " not found");
  if (!is_model_input(a.input))
    return invalid_argument(a.input + " is neither a run folder (with run.json or model.hbgs), a model file (.hbgs, .hbgc) nor "
                            "a splat file (" + std::string(io::supported_splat_extensions()) + ")");
  pose::PoseNoise noise;
  if (Status st = pose::parse_pose_noise(a.init_noise, &noise); !st.ok())
    return invalid_argument("--init-noise: " + st.message());
  Expected<ModelViews> loaded = load_model_views(a.input, a.dataset, -1, a.views);
  if (!loaded.ok()) return loaded.status();
  const ModelSource* src = &loaded->source;
  io::Dataset& ds = loaded->data->dataset;
  Expected<model::Background> background = model_background(*src, a.background);
  if (!background.ok()) return background.status();
  std::copy(background->rgb, background->rgb + 3, ro->background);
  const float extent = loaded->scene_extent();  // before the noise moves the split's cameras
  // True poses and the scene frame of the training cameras; the start poses are the perturbed ones.
  PoseTruth truth;
  if (Status st = apply_pose_noise(&ds, a.init_noise, a.views, &truth); !st.ok())
    return invalid_argument("--init-noise: " + st.message());
  const std::string out = a.out.empty() ? (fs::path(src->run_dir) / "register").string() : a.out;
  if (platform::file_exists(out) && !platform::is_directory(out))
    return invalid_argument("output " + out + " exists and is not a directory");

  std::vector<size_t> index;  // dataset indices of the split, in name order (the dataset is sorted)
  std::vector<std::string> names;
  int max_w = 0, max_h = 0;
  for (size_t i = 0; i < ds.views.size(); ++i) {
    const io::DatasetView& v = ds.views[i];
    if (!(a.views == "all" || (a.views == "test") == v.is_test)) continue;
    index.push_back(i);
    names.push_back(v.name);
    max_w = std::max(max_w, v.camera.intr.width);
    max_h = std::max(max_h, v.camera.intr.height);
  }

  RegisterViewsSummary s;
  // One registrar for every view: planned once, then allocation-free.
  platform::ThreadPool pool(a.threads);
  Expected<std::unique_ptr<pose::Registrar>> reg =
      loaded->cloud ? pose::Registrar::create(*loaded->cloud, extent, max_w, max_h, *ro, &pool)
                    : pose::Registrar::create(loaded->model, max_w, max_h, *ro, &pool);
  if (!reg.ok()) return reg.status();
  const double t0 = platform::now_seconds();
  // Relocalisation candidates: the views outside the split, at their dataset poses (never a view's
  // own pose), when they share the split's image size.
  std::vector<size_t> cand_index;
  if (a.relocalize > 0 && !index.empty()) {
    const PinholeIntrinsics& intr = ds.views[index[0]].camera.intr;
    std::vector<Pose> poses;
    for (size_t i = 0, k = 0; i < ds.views.size(); ++i) {
      if (k < index.size() && index[k] == i) { ++k; continue; }
      const PinholeIntrinsics& ci = ds.views[i].camera.intr;
      if (ci.width != intr.width || ci.height != intr.height) continue;
      cand_index.push_back(i);
      poses.push_back(truth.poses[i]);
    }
    GS_RETURN_IF_ERROR((*reg)->set_candidates(poses, intr));
  }
  const double radius = truth.radius * truth.unit;
  std::vector<Pose> estimated;
  GS_RETURN_IF_ERROR(register_split(**reg, ds, index, truth, cand_index, background->rgb, progress, &s.views, &estimated));
  reg->reset();  // its arena is not needed for the metrics below (peak memory: one renderer at a time)

  model::EvalOptions eo;
  std::copy(background->rgb, background->rgb + 3, eo.render.background);
  eo.render.fixed_point_raster = a.fixed_point;
  if (a.fixed_point) eo.render.int8_mlp = loaded->compact.get();  // int8 MLPs when the file is compact
  model::EvalResult m_start, m_reg;
  GS_RETURN_IF_ERROR(evaluate_split(*loaded, ds, index, estimated, eo, &pool, &m_start, &m_reg));

  const SplitFigures f = split_figures(s.views);
  const nlohmann::ordered_json j = register_views_json(a, *loaded, pose::describe(noise), pool.num_threads(), radius, s.views, f,
                                                       m_start, m_reg, platform::now_seconds() - t0, cand_index.size());
  GS_RETURN_IF_ERROR(platform::make_dirs(out));
  const std::string json_path = (fs::path(out) / kRegisterJson).string();
  const std::string text = j.dump(2) + "\n";
  GS_RETURN_IF_ERROR(platform::write_file_atomic(json_path, text));
  if (!a.json.empty()) GS_RETURN_IF_ERROR(platform::write_file_atomic(a.json, text));
  const std::string posed = (fs::path(out) / "registered").string();
  GS_RETURN_IF_ERROR(write_posed_model(src->dataset, names, estimated, posed, loaded->frame()));

  s.source = *src;
  s.noise = pose::describe(noise);
  s.json_path = json_path;
  s.posed_dir = posed;
  s.scene_radius = radius;
  s.median_initial_rotation_deg = median(f.init_rot);
  s.median_initial_translation = median(f.init_trans);
  s.median_rotation_deg = median(f.rot);
  s.median_translation = median(f.trans);
  s.success = f.success;
  s.converged = f.converged;
  s.relocalized = f.relocalized;
  s.candidates = cand_index.size();
  s.median_ms = median(f.ms);
  s.mean_ms = mean(f.ms);
  s.total_seconds = platform::now_seconds() - t0;
  s.psnr_at_start = m_start.psnr;
  s.ssim_at_start = m_start.ssim;
  s.psnr_registered = m_reg.psnr;
  s.ssim_registered = m_reg.ssim;
  s.threads = pool.num_threads();
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

}  // namespace gs::jobs
