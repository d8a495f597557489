// SPDX-License-Identifier: MIT
// `hbgs train`: trains the hybrid anchor model on a COLMAP dataset into a run folder (run.json,
// checkpoint.bin + progress.json, psnr_vs_time.csv/.svg, model files, test renders, results.json
// and per_view.json), resumable from its last checkpoint.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include <nlohmann/json.hpp>

#include "common.h"
#include "gs/model/point_alignment.h"
#include "gs/model/trainer.h"
#include "gs/capture/sfm_images.h"
#include "gs/capture/sfm_pose_init.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "gs/simd/kernel_table.h"
#include "model_run.h"
#include "pose_cli.h"

namespace hbgs::cli {
namespace {

namespace fs = std::filesystem;
constexpr const char* kCmd = "train";
constexpr const char* kPsnrCsv = "psnr_vs_time.csv";
constexpr const char* kPsnrSvg = "psnr_vs_time.svg";

// One point of the PSNR-vs-time curve: test PSNR after `iteration`, reached after `seconds` of
// training (wall clock of the training steps only; evaluation and file writing excluded).
struct PsnrRow {
  int iteration = 0;
  double seconds = 0, psnr = 0;
};

// Training-time figures saved next to each checkpoint, so a resumed run continues them.
struct Progress {
  int iteration = 0;
  double train_seconds = 0;
  std::vector<PsnrRow> rows;
  std::vector<float> iteration_ms;  // one per iteration, in order
};

gs::Expected<std::vector<int>> parse_save_at(const std::string& text) {
  std::vector<int> out;
  std::istringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    if (part.empty()) continue;
    size_t used = 0;
    long v = 0;
    try {
      v = std::stol(part, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != part.size() || v < 1 || v > 100000000)
      return gs::invalid_argument("--save-at: '" + part + "' is not a positive iteration number");
    out.push_back(int(v));
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// Tick spacing of 1, 2 or 5 x 10^k giving about `target` ticks over range.
double nice_step(double range, int target) {
  const double raw = std::max(range, 1e-9) / target;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10.0 * p;
}

// Hand-written SVG line plot of test PSNR against training seconds.
std::string psnr_svg(const std::vector<PsnrRow>& rows, const std::string& title) {
  const double W = 720, H = 440, left = 70, right = 24, top = 44, bottom = 62;
  const double pw = W - left - right, ph = H - top - bottom;
  double xmax = 1, ymin = 1e9, ymax = -1e9;
  for (const PsnrRow& r : rows) {
    xmax = std::max(xmax, r.seconds);
    if (std::isfinite(r.psnr)) ymin = std::min(ymin, r.psnr), ymax = std::max(ymax, r.psnr);
  }
  if (ymin > ymax) ymin = 0, ymax = 40;
  const double ystep = nice_step(std::max(ymax - ymin, 1.0), 6);
  ymin = std::floor(ymin / ystep) * ystep;
  ymax = std::max(std::ceil(ymax / ystep) * ystep, ymin + ystep);
  const double xstep = nice_step(xmax, 6);
  xmax = std::ceil(xmax / xstep) * xstep;
  auto X = [&](double x) { return left + pw * x / xmax; };
  auto Y = [&](double y) { return top + ph * (1 - (y - ymin) / (ymax - ymin)); };

  std::string s = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"720\" height=\"440\" viewBox=\"0 0 720 440\" "
                  "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"720\" height=\"440\" fill=\"white\"/>\n";
  s += "<text x=\"360\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">" + title + "</text>\n";
  for (double y = ymin; y <= ymax + 1e-9; y += ystep) {
    const std::string py = fmt("%.1f", Y(y));
    s += "<line x1=\"" + fmt("%.1f", left) + "\" x2=\"" + fmt("%.1f", left + pw) + "\" y1=\"" + py + "\" y2=\"" + py +
         "\" stroke=\"#ddd\"/>\n<text x=\"" + fmt("%.1f", left - 6) + "\" y=\"" + py +
         "\" text-anchor=\"end\" dominant-baseline=\"middle\">" + fmt(ystep < 1 ? "%.1f" : "%.0f", y) + "</text>\n";
  }
  for (double x = 0; x <= xmax + 1e-9; x += xstep) {
    const std::string px = fmt("%.1f", X(x));
    s += "<line x1=\"" + px + "\" x2=\"" + px + "\" y1=\"" + fmt("%.1f", top) + "\" y2=\"" + fmt("%.1f", top + ph) +
         "\" stroke=\"#ddd\"/>\n<text x=\"" + px + "\" y=\"" + fmt("%.1f", top + ph + 18) +
         "\" text-anchor=\"middle\">" + fmt(xstep < 1 ? "%.1f" : "%.0f", x) + "</text>\n";
  }
  s += "<rect x=\"" + fmt("%.1f", left) + "\" y=\"" + fmt("%.1f", top) + "\" width=\"" + fmt("%.1f", pw) +
       "\" height=\"" + fmt("%.1f", ph) + "\" fill=\"none\" stroke=\"black\"/>\n";
  s += "<text x=\"" + fmt("%.1f", left + pw / 2) + "\" y=\"" + fmt("%.1f", H - 16) +
       "\" text-anchor=\"middle\">training time (s, evaluation excluded)</text>\n";
  s += "<text transform=\"translate(18 " + fmt("%.1f", top + ph / 2) +
       ") rotate(-90)\" text-anchor=\"middle\">test PSNR (dB)</text>\n";
  std::string points;
  for (const PsnrRow& r : rows)
    if (std::isfinite(r.psnr)) points += fmt("%.1f", X(r.seconds)) + "," + fmt("%.1f", Y(r.psnr)) + " ";
  s += "<polyline fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"2\" points=\"" + points + "\"/>\n";
  for (const PsnrRow& r : rows)
    if (std::isfinite(r.psnr))
      s += "<circle cx=\"" + fmt("%.1f", X(r.seconds)) + "\" cy=\"" + fmt("%.1f", Y(r.psnr)) +
           "\" r=\"2.5\" fill=\"#1f77b4\"><title>iteration " + std::to_string(r.iteration) + ": " +
           fmt("%.2f", r.psnr) + " dB at " + fmt("%.1f", r.seconds) + " s</title></circle>\n";
  return s + "</svg>\n";
}

gs::Status write_psnr_files(const std::string& run, const std::vector<PsnrRow>& rows, const std::string& title) {
  std::string csv = "iteration,train_seconds,test_psnr\n";
  for (const PsnrRow& r : rows)
    csv += std::to_string(r.iteration) + "," + fmt("%.3f", r.seconds) + "," + fmt("%.4f", r.psnr) + "\n";
  GS_RETURN_IF_ERROR(gs::platform::write_file_atomic((fs::path(run) / kPsnrCsv).string(), csv));
  return gs::platform::write_file_atomic((fs::path(run) / kPsnrSvg).string(), psnr_svg(rows, title));
}

gs::Status save_progress(const std::string& run, const Progress& p) {
  nlohmann::json j;
  j["iteration"] = p.iteration;
  j["train_seconds"] = p.train_seconds;
  nlohmann::json rows = nlohmann::json::array();
  for (const PsnrRow& r : p.rows) rows.push_back({r.iteration, r.seconds, std::isfinite(r.psnr) ? r.psnr : 0.0});
  j["psnr_rows"] = std::move(rows);
  j["iteration_ms"] = p.iteration_ms;
  return gs::platform::write_file_atomic((fs::path(run) / kProgressFile).string(), j.dump() + "\n");
}

// Progress at checkpoint iteration `at`. progress.json is written right after checkpoint.bin, so a
// kill between the two leaves it one checkpoint behind: its time is then extended by the median
// iteration time, and anything past `at` is dropped.
Progress load_progress(const std::string& run, int at) {
  Progress p;
  gs::Expected<std::string> text = gs::platform::read_text_file((fs::path(run) / kProgressFile).string());
  nlohmann::json j = text.ok() ? nlohmann::json::parse(*text, nullptr, false) : nlohmann::json();
  if (!j.is_object()) {
    std::fprintf(stderr, "note: %s/%s is missing or unreadable; PSNR-vs-time restarts at iteration %d\n", run.c_str(),
                 kProgressFile, at);
    p.iteration = at;
    return p;
  }
  const int saved = j.value("iteration", 0);
  p.train_seconds = j.value("train_seconds", 0.0);
  for (const auto& r : j.value("psnr_rows", nlohmann::json::array()))
    if (r.is_array() && r.size() == 3 && r[0].get<int>() <= at) p.rows.push_back({r[0].get<int>(), r[1].get<double>(), r[2].get<double>()});
  p.iteration_ms = j.value("iteration_ms", std::vector<float>());
  if (p.iteration_ms.size() > size_t(at)) p.iteration_ms.resize(size_t(at));
  if (saved != at) {
    const double ms = gs::median(std::vector<double>(p.iteration_ms.begin(), p.iteration_ms.end()));
    if (saved < at) p.train_seconds += 1e-3 * ms * (at - saved);
    else if (!p.rows.empty()) p.train_seconds = p.rows.back().seconds;
    std::fprintf(stderr, "note: %s was saved at iteration %d, the checkpoint at %d; training time estimated\n",
                 kProgressFile, saved, at);
  }
  p.iteration = at;
  return p;
}

// Files a previous run left in `run` (removed by --force; their presence refuses a plain train).
std::vector<fs::path> run_outputs(const std::string& run) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const char* name : {kRunJson, kCheckpointFile, kProgressFile, kPsnrCsv, kPsnrSvg, kResultsJson, kPerViewJson,
                           kModelFile, "test"})
    if (fs::exists(fs::path(run) / name, ec)) out.push_back(fs::path(run) / name);
  for (fs::directory_iterator it(run, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("model_", 0) == 0 && it->path().extension() == ".hbgs") out.push_back(it->path());
  }
  return out;
}

// With --resume, options not given on the command line come from run.json; model options given
// there must match it (the checkpoint holds a model built with them).
gs::Status apply_recorded_options(const std::string& run, TrainArgs* a) {
  gs::Expected<std::string> text = gs::platform::read_text_file((fs::path(run) / kRunJson).string());
  if (!text.ok()) return text.status();
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  if (!j.is_object() || !j.contains("options")) return gs::parse_error(run + "/" + kRunJson + ": not a hbgs run file");
  const std::string recorded = j.value("dataset", std::string());
  if (recorded != absolute_path(a->dataset))
    return gs::invalid_argument("the run in " + run + " was trained on " + recorded + ", not " + absolute_path(a->dataset));
  const nlohmann::json& o = j["options"];
  const std::set<std::string> given(a->given.begin(), a->given.end());
  std::string conflicts;
  auto take = [&](const char* key, auto* field, bool model_option) {
    using T = std::decay_t<decltype(*field)>;
    if (!o.contains(key)) return;
    const T value = o[key].get<T>();
    if (!given.count(key)) *field = value;
    else if (model_option && !(value == *field)) conflicts += std::string(conflicts.empty() ? "" : ", ") + "--" + key;
  };
  take("image-features", &a->image_features, true);
  take("max-anchors", &a->max_anchors, true);
  take("max-gaussians", &a->max_gaussians, true);
  take("voxel-size", &a->voxel_size, true);
  take("seed", &a->seed, true);
  take("pose-noise", &a->pose_noise, true);
  take("pose-noise-on", &a->pose_noise_on, true);
  take("optimize-poses", &a->optimize_poses, true);
  take("coarse-levels", &a->coarse_levels, true);
  take("feature-refresh", &a->feature_refresh, true);
  take("pose-lr", &a->pose_lr, true);
  take("point-align", &a->point_align, true);
  take("register-passes", &a->register_passes, true);
  take("pose-init", &a->pose_init, true);
  take("sfm-images", &a->sfm_images, true);
  take("max-width", &a->max_width, true);
  take("iterations", &a->iterations, false);
  take("checkpoint-every", &a->checkpoint_every, false);
  take("eval-every", &a->eval_every, false);
  take("save-at", &a->save_at, false);
  take("lpips-weights", &a->lpips_weights, false);
  if (!conflicts.empty())
    return gs::invalid_argument(conflicts + " differ from the run being resumed (see " + run + "/" + kRunJson + ")");
  return gs::Status::Ok();
}

std::string run_json(const TrainArgs& a) {
  nlohmann::json j;
  j["format"] = "hbgs-run";
  j["dataset"] = absolute_path(a.dataset);
  j["max_width"] = a.max_width;
  j["options"] = {{"iterations", a.iterations},         {"image-features", a.image_features},
                  {"max-anchors", a.max_anchors},       {"max-gaussians", a.max_gaussians},
                  {"voxel-size", a.voxel_size},         {"seed", a.seed},
                  {"max-width", a.max_width},           {"checkpoint-every", a.checkpoint_every},
                  {"eval-every", a.eval_every},         {"save-at", a.save_at},
                  {"lpips-weights", a.lpips_weights},   {"threads", a.threads},
                  {"pose-noise", a.pose_noise},         {"pose-noise-on", a.pose_noise_on},
                  {"optimize-poses", a.optimize_poses}, {"coarse-levels", a.coarse_levels},
                  {"feature-refresh", a.feature_refresh},
                  {"pose-lr", a.pose_lr},               {"point-align", a.point_align},
                  {"register-passes", a.register_passes}, {"pose-init", a.pose_init},
                  {"sfm-images", a.sfm_images}};
  return j.dump(2) + "\n";
}

std::string clock_text(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--";
  const long s = long(seconds + 0.5);
  char buf[32];
  if (s >= 3600) std::snprintf(buf, sizeof(buf), "%ld:%02ld:%02ld", s / 3600, s / 60 % 60, s % 60);
  else std::snprintf(buf, sizeof(buf), "%ld:%02ld", s / 60, s % 60);
  return buf;
}

// The progress line on stderr: rewritten in place on a terminal (at most every second or 50
// iterations), a plain line every 5 s otherwise.
class ProgressLine {
 public:
  ProgressLine(int total, bool quiet) : total_(total), quiet_(quiet), tty_(isatty(fileno(stderr)) != 0) {}
  void update(const gs::model::IterationStats& s) {
    if (s.poses_registered >= 0 && !quiet_) {
      break_line();
      std::fprintf(stderr, "it %d: registration pass moved %d poses\n", s.iteration, s.poses_registered);
    }
    ema_loss_ = have_ ? 0.6 * ema_loss_ + 0.4 * s.step.loss : s.step.loss;
    ema_psnr_ = have_ ? 0.6 * ema_psnr_ + 0.4 * s.psnr : s.psnr;
    have_ = true;
    ++since_;
    const double now = gs::platform::now_seconds(), dt = now - last_;
    const bool last = s.iteration == total_;
    if (quiet_ || !(last || (tty_ ? (dt >= 1.0 || s.iteration % 50 == 0) : dt >= 5.0))) return;
    rate_ = since_ / std::max(dt, 1e-9);
    since_ = 0;
    last_ = now;
    std::fprintf(stderr, "%sit %d/%d  loss %.4f  train PSNR %.2f  anchors %zu  Gaussians %zu  %.1f it/s  ETA %s%s",
                 tty_ ? "\r\033[K" : "", s.iteration, total_, ema_loss_, ema_psnr_, s.anchors, s.step.gaussians, rate_,
                 clock_text((total_ - s.iteration) / rate_).c_str(), tty_ ? "" : "\n");
    std::fflush(stderr);
    open_ = tty_;
  }
  // Ends the in-place line before other output.
  void break_line() {
    if (open_) std::fputc('\n', stderr);
    open_ = false;
  }

 private:
  int total_;
  bool quiet_, tty_, have_ = false, open_ = false;
  double ema_loss_ = 0, ema_psnr_ = 0, rate_ = 0, last_ = gs::platform::now_seconds();
  int since_ = 0;
};

}  // namespace

int run_train(const TrainArgs& args, TrainSummary* summary) {
  // 1. Everything that can be wrong with the inputs is checked before the run folder is touched.
  TrainArgs a = args;
  std::error_code ec;
  if (!gs::platform::is_directory(a.dataset)) return fail(kCmd, "dataset folder " + a.dataset + " not found");
  if (a.resume && a.force) return fail(kCmd, "--resume and --force contradict each other; choose one");
  if (fs::exists(a.out, ec) && !fs::is_directory(a.out, ec)) return fail(kCmd, "output " + a.out + " is not a directory");
  const std::string ckpt = (fs::path(a.out) / kCheckpointFile).string();
  const std::vector<fs::path> previous = fs::is_directory(a.out, ec) ? run_outputs(a.out) : std::vector<fs::path>();
  if (a.resume) {
    if (!gs::platform::file_exists(ckpt)) return fail(kCmd, "nothing to resume: " + ckpt + " not found");
    if (gs::Status st = apply_recorded_options(a.out, &a); !st.ok()) return fail(kCmd, "--resume: " + st.to_string());
    // A run killed while writing leaves its atomic-write temporaries ("<file>.tmp.<pid>"); the
    // real files are intact (renamed only when complete), so the leftovers are simply removed.
    for (const fs::directory_entry& e : fs::directory_iterator(a.out, ec))
      if (e.path().filename().string().find(".tmp.") != std::string::npos) fs::remove(e.path(), ec);
  } else if (!previous.empty() && !a.force) {
    return fail(kCmd, a.out + " already holds a run (" + previous.front().string() +
                          " exists); pass --force to overwrite it or --resume to continue it");
  }
  gs::Expected<std::vector<int>> save_at = parse_save_at(a.save_at);
  if (!save_at.ok()) return fail(kCmd, save_at.status().message());
  if (a.pose_init == "sfm") {
    if (!a.optimize_poses) return fail(kCmd, "--pose-init sfm needs --optimize-poses");
    if (gs::Status st = gs::capture::check_sfm_images_choice(a.dataset, a.sfm_images); !st.ok()) return fail(kCmd, "--sfm-images: " + st.message());
    gs::capture::ColmapOptions copt;
    copt.colmap = a.colmap;
    if (gs::Status st = gs::capture::check_colmap(copt); !st.ok()) return fail(kCmd, "--pose-init sfm: " + st.message());
  }
  gs::Expected<gs::model::ImageFeatureMode> mode = gs::model::parse_image_feature_mode(a.image_features);
  if (!mode.ok()) return fail(kCmd, "--image-features: " + mode.status().to_string());

  gs::Expected<std::unique_ptr<LoadedDataset>> data = load_dataset_split(a.dataset, a.max_width, "all");
  if (!data.ok()) return fail(kCmd, data.status().to_string());
  gs::io::Dataset& ds = (*data)->dataset;
  PoseTruth truth;
  if (gs::Status st = apply_pose_noise(&ds, a.pose_noise, a.pose_noise_on, &truth); !st.ok()) return fail(kCmd, st.message());
  const size_t npoints = ds.points_xyz.size() / 3;
  if (npoints == 0)
    return fail(kCmd, a.dataset + ": the dataset has no SfM points (sparse/0/points3D); training places its anchors on them");
  std::vector<const gs::io::DatasetView*> train_views, test_views;
  std::vector<const gs::Camera*> train_cameras;
  std::vector<size_t> train_index;  // dataset index of each training view
  std::vector<std::string> train_names;
  for (size_t i = 0; i < ds.views.size(); ++i) {
    const gs::io::DatasetView& v = ds.views[i];
    (v.is_test ? test_views : train_views).push_back(&v);
    if (!v.is_test) {
      train_cameras.push_back(&v.camera);
      train_index.push_back(i);
      train_names.push_back(v.name);
    }
  }
  if (train_views.empty()) return fail(kCmd, a.dataset + ": no training views (every view is a test view)");

  // Training-pose errors of the input (before any alignment), for the report.
  std::vector<gs::Pose> input_poses;
  for (const gs::io::DatasetView* v : train_views) input_poses.push_back(v->camera.pose);
  const gs::pose::PoseErrors input_errors = errors_for(input_poses, train_index, truth, true);
  gs::platform::ThreadPool pool(a.threads);
  nlohmann::json sfm_init_json;
  if (a.optimize_poses && a.pose_init == "sfm" && !a.resume) {
    // Stage 0: global initialisation by structure from motion (gs/capture/sfm_pose_init.h).
    gs::capture::SfmPoseInitOptions so;
    so.colmap.colmap = a.colmap;
    so.colmap.matcher = gs::capture::Matcher::kExhaustive;
    so.colmap.threads = a.threads;
    gs::Expected<gs::capture::SfmImages> sfm_images = gs::capture::choose_sfm_images(a.dataset, a.sfm_images, train_views, so.colmap.max_image_size);
    if (!sfm_images.ok()) return fail(kCmd, "--sfm-images: " + sfm_images.status().message());
    std::vector<gs::Camera> cams = sfm_images->cameras;
    std::vector<const gs::io::Image8*> images;
    for (size_t i = 0; i < train_views.size(); ++i)
      images.push_back(sfm_images->folder.empty() ? &train_views[i]->image : &sfm_images->images[i]);
    gs::capture::SfmPoseInitReport rep;
    if (!a.quiet) {
      if (!sfm_images->note.empty()) std::fprintf(stderr, "hbgs train: note: %s\n", sfm_images->note.c_str());
      std::fprintf(stderr, "hbgs train: initialising %zu training poses by structure from motion (COLMAP on %s, %dx%d)...\n",
                   cams.size(), sfm_images->folder.empty() ? "the training images" : sfm_images->folder.c_str(),
                   cams[0].intr.width, cams[0].intr.height);
    }
    const gs::capture::ProgressFn progress = [&](const std::string& line) {
      if (!a.quiet) std::fprintf(stderr, "  %s\n", line.c_str());
    };
    if (gs::Status st = gs::capture::init_poses_by_sfm(images, train_names, &cams, ds.points_xyz.data(), npoints,
                                                       a.out + "/sfm_init", so, progress, &rep);
        !st.ok())
      return fail(kCmd, "--pose-init sfm: " + st.message());
    for (size_t i = 0; i < cams.size(); ++i) ds.views[train_index[i]].camera.pose = cams[i].pose;
    std::vector<gs::Pose> now;
    for (const gs::Camera& c : cams) now.push_back(c.pose);
    const gs::pose::PoseErrors e = errors_for(now, train_index, truth, true);
    sfm_init_json = {{"seconds", rep.seconds},           {"registered", rep.registered},
                     {"images", sfm_images->folder.empty() ? std::string("training images") : sfm_images->folder},
                     {"image_width", cams[0].intr.width}, {"image_height", cams[0].intr.height},
                     {"views", rep.views},               {"colmap_points", rep.colmap_points},
                     {"centre_fit_rms", rep.centre_fit_rms}, {"icp_median_before", rep.icp_median_before},
                     {"icp_median_after", rep.icp_median_after}, {"icp_pairs", rep.icp_pairs},
                     {"icp_iterations", rep.icp_iterations}, {"errors", pose_errors_json(e, false)}};
    if (!a.quiet)
      std::fprintf(stderr,
                   "hbgs train: SfM initialisation in %.1f s: %d of %d views registered; rotation mean %.3f deg (was %.3f), "
                   "translation %.2f%% of radius (was %.2f%%); ICP median distance %.4f -> %.4f\n",
                   rep.seconds, rep.registered, rep.views, e.rotation_mean_deg, input_errors.rotation_mean_deg,
                   100 * e.translation_mean_frac, 100 * input_errors.translation_mean_frac, rep.icp_median_before,
                   rep.icp_median_after);
  }
  nlohmann::json point_alignment_json;
  if (a.optimize_poses && a.point_align && !a.resume) {
    // Stage 1: align the training poses to the SfM points (photometric, no model needed).
    std::vector<gs::Camera> cams;
    std::vector<const gs::io::Image8*> images;
    for (const gs::io::DatasetView* v : train_views) cams.push_back(v->camera), images.push_back(&v->image);
    gs::model::PointAlignReport rep;
    if (!a.quiet) std::fprintf(stderr, "hbgs train: aligning %zu training poses to the SfM points...\n", cams.size());
    gs::model::PointAlignOptions pao;
    if (a.pose_init == "sfm") {
      // When SfM placed the views within the colour objective's own precision (a median move
      // under 0.5 degrees: snowmiku_plush 0.127 -> 0.207 deg mean with it), its poses are kept;
      // otherwise (the built-in scene: about 1 degree from SfM, 0.05 after) a view that moved
      // more than 3x the median (an occluder without SfM points in front of it pulled snowmiku's
      // close-ups 5-17 degrees) keeps its SfM pose.
      pao.discard_below_median_move_deg = 0.5;
      pao.max_move_over_median = 3;
    }
    if (gs::Status st = gs::model::align_poses_to_points(ds.points_xyz.data(), ds.points_rgb.empty() ? nullptr : ds.points_rgb.data(), npoints, images, &cams, pao, &pool, &rep); !st.ok())
      return fail(kCmd, st.to_string());
    for (size_t i = 0; i < cams.size(); ++i) ds.views[train_index[i]].camera.pose = cams[i].pose;
    std::vector<gs::Pose> aligned;
    for (const gs::Camera& c : cams) aligned.push_back(c.pose);
    const gs::pose::PoseErrors e = errors_for(aligned, train_index, truth, true);
    nlohmann::json reverted = nlohmann::json::array();
    for (int v : rep.reverted_views) reverted.push_back(train_names[size_t(v)]);
    point_alignment_json = {{"seconds", rep.seconds}, {"points", rep.points_used}, {"levels", rep.levels},
                            {"rounds", rep.rounds}, {"kept_start_pose", reverted}, {"median_move_deg", rep.median_move_deg},
                            {"median_move_fraction_of_radius", rep.median_move_frac}, {"discarded", rep.discarded},
                            {"errors", pose_errors_json(e, false)}};
    if (!a.quiet)
      std::fprintf(stderr,
                   "hbgs train: point alignment in %.1f s: rotation mean %.3f deg (was %.3f), translation %.2f%% of radius "
                   "(was %.2f%%); median move %.3f deg; %s\n",
                   rep.seconds, e.rotation_mean_deg, input_errors.rotation_mean_deg, 100 * e.translation_mean_frac,
                   100 * input_errors.translation_mean_frac, rep.median_move_deg,
                   rep.discarded ? "within the method's precision, so every view keeps its SfM pose"
                                 : (std::to_string(rep.reverted_views.size()) + " views moved over 3x the median kept their SfM pose").c_str());
  }

  gs::model::ModelConfig config;
  config.image_features = *mode;
  config.max_anchors = a.max_anchors;
  config.max_gaussians = a.max_gaussians;
  config.voxel_size = a.voxel_size;
  gs::Expected<gs::model::HybridModel> model = gs::model::create_model(
      config, ds.points_xyz.data(), npoints, gs::model::cameras_extent(train_cameras), a.seed);
  if (!model.ok()) return fail(kCmd, model.status().to_string());
  gs::model::TrainOptions topt;
  topt.iterations = a.iterations;
  topt.schedule_iterations = a.iterations;
  topt.seed = a.seed;
  topt.optimize_poses = a.optimize_poses;
  // Coarse to fine helps poses a few degrees off; after --pose-init sfm they are already close, and
  // the low-resolution phase would only cost detail (measured: 28.31 against 28.69 dB on synth).
  topt.coarse_levels = a.coarse_levels >= 0 ? a.coarse_levels : (a.optimize_poses && a.pose_init != "sfm" ? 2 : 0);
  topt.lr_pose_rotation_init = topt.lr_pose_translation_init = a.pose_lr;
  topt.image_feature_refresh = a.feature_refresh >= 0 ? a.feature_refresh : (a.optimize_poses ? 250 : 0);  // features follow moving poses
  if (a.optimize_poses) {
    topt.pose_warmup = std::max(1, a.iterations / 10);
    if (a.register_passes > 0) {
      topt.pose_register_every = std::max(1, a.iterations / (2 * a.register_passes));
      topt.pose_register_until = a.iterations / 2;
    }
  }
  gs::Expected<std::unique_ptr<gs::model::Trainer>> created =
      gs::model::Trainer::create(std::move(model).value(), train_views, topt, &pool);
  if (!created.ok()) return fail(kCmd, created.status().to_string());
  gs::model::Trainer& trainer = **created;
  if (a.resume)
    if (gs::Status st = trainer.load_checkpoint(ckpt); !st.ok())
      return fail(kCmd, "cannot resume from " + ckpt + ": " + st.to_string());
  gs::Expected<std::unique_ptr<gs::metrics::LpipsAlex>> lpips = load_lpips(a.lpips_weights, a.threads, a.quiet);
  if (!lpips.ok()) return fail(kCmd, lpips.status().to_string());

  // Training-pose errors against the true poses (Sim(3)-aligned on camera centres), input and current.
  auto current_train_poses = [&] {
    std::vector<gs::Pose> out;
    for (const gs::Camera& c : trainer.cameras()) out.push_back(c.pose);
    return out;
  };
  auto pose_json = [&] {
    const std::vector<gs::Pose> now = current_train_poses();
    return nlohmann::json{{"noise", a.pose_noise},
                          {"noise_on", a.pose_noise_on},
                          {"optimized", a.optimize_poses},
                          {"scene_radius", truth.radius},
                          {"train_input", pose_errors_json(input_errors, false)},
                          {"sfm_init", sfm_init_json},
                          {"point_alignment", point_alignment_json},
                          {"train_final", pose_errors_json(errors_for(now, train_index, truth, true), true, train_names)},
                          {"train_final_unaligned", pose_errors_json(errors_for(now, train_index, truth, false), false)}};
  };

  // 2. The run folder.
  if (a.force)
    for (const fs::path& p : previous)
      if (fs::remove_all(p, ec), ec) return fail(kCmd, "cannot remove " + p.string() + ": " + ec.message());
  if (gs::Status st = gs::platform::make_dirs(a.out); !st.ok()) return fail(kCmd, st.to_string());
  if (gs::Status st = gs::platform::write_file_atomic((fs::path(a.out) / kRunJson).string(), run_json(a)); !st.ok())
    return fail(kCmd, st.to_string());

  const std::string title = "Test PSNR vs training time: " + fs::path(absolute_path(a.dataset)).filename().string();
  Progress progress = a.resume ? load_progress(a.out, trainer.iteration()) : Progress{};
  const int resumed_from = a.resume ? trainer.iteration() : -1;
  const bool have_test = !test_views.empty();
  if (!have_test && !a.quiet) std::fprintf(stderr, "note: the dataset has no test views; nothing is evaluated\n");
  const gs::metrics::LpipsAlex* net = lpips->get();
  const gs::simd::KernelTable& kernels = gs::simd::best_kernel_table();
  if (!a.quiet)
    std::fprintf(stderr, "hbgs train: %s, %zu train + %zu test views, %zu points, %zu anchors, image features %s, ISA %s, %d threads%s\n",
                 a.dataset.c_str(), train_views.size(), test_views.size(), npoints, trainer.model().anchor_count,
                 a.image_features.c_str(), kernels.isa, pool.num_threads(),
                 a.resume ? (", resuming at iteration " + std::to_string(trainer.iteration())).c_str() : "");

  ProgressLine line(a.iterations, a.quiet);
  gs::model::EvalResult final_eval;
  auto record_psnr = [&](int it, double psnr) -> gs::Status {
    progress.rows.erase(std::remove_if(progress.rows.begin(), progress.rows.end(),
                                       [it](const PsnrRow& r) { return r.iteration >= it; }),
                        progress.rows.end());
    progress.rows.push_back({it, progress.train_seconds, psnr});
    return write_psnr_files(a.out, progress.rows, title);
  };
  // Saves the model as model_file, evaluates every test view fully (PNGs, SSIM, LPIPS) and merges
  // the figures as "ours_<it>" into results.json / per_view.json.
  auto full_eval = [&](int it, const std::string& model_file) -> gs::Status {
    const gs::model::HybridModel& m = trainer.model();
    GS_RETURN_IF_ERROR(gs::model::save_model(m, model_file));
    if (!have_test) return gs::Status::Ok();
    const std::string method = "ours_" + std::to_string(it);
    gs::model::EvalOptions eo;
    eo.lpips = net;
    eo.render_dir = (fs::path(a.out) / "test" / method / "renders").string();
    gs::Expected<gs::model::EvalResult> r = gs::model::evaluate_views(m, test_views, eo, &pool);
    if (!r.ok()) return r.status();
    double gaussians = 0;
    for (const gs::model::ViewMetrics& v : r->views) gaussians += double(v.gaussians);
    nlohmann::json extra = {
        {"iterations", it},
        {"train_seconds", progress.train_seconds},
        {"median_iteration_ms", gs::median(std::vector<double>(progress.iteration_ms.begin(), progress.iteration_ms.end()))},
        {"model_bytes", m.file_bytes()},
        {"model_file_bytes", file_size_or_zero(model_file)},
        {"anchors", m.anchor_count},
        {"mean_gaussians_per_view", gaussians / double(r->views.size())},
        {"render_ms_median", r->render_ms_median},
        {"image_features", gs::model::image_feature_mode_name(m.config.image_features)},
        {"test_views", r->views.size()},
        {"isa", kernels.isa},
        {"threads", pool.num_threads()}};
    if (net) extra["lpips_backbone"] = gs::metrics::LpipsAlex::kLabel;
    extra["test_poses"] = a.pose_noise_on == "train" ? "true (dataset) poses, not registered" : "noisy poses, not registered";
    extra["poses"] = pose_json();
    GS_RETURN_IF_ERROR(write_eval_files(a.out, method, *r, json_members(extra.dump())));
    if (a.eval_every > 0) GS_RETURN_IF_ERROR(record_psnr(it, r->psnr));
    final_eval = std::move(r).value();
    return gs::Status::Ok();
  };
  // model_<it>.hbgs at the --save-at iterations, model.hbgs otherwise (the final one).
  auto model_file_for = [&](int it) {
    const bool listed = std::binary_search(save_at->begin(), save_at->end(), it);
    return (fs::path(a.out) / (listed ? "model_" + std::to_string(it) + ".hbgs" : std::string(kModelFile))).string();
  };
  auto checkpoint = [&]() -> gs::Status {
    GS_RETURN_IF_ERROR(trainer.save_checkpoint(ckpt));
    progress.iteration = trainer.iteration();
    return save_progress(a.out, progress);
  };

  // 3. Train.
  if (!a.resume && a.eval_every > 0 && have_test) {
    gs::model::EvalOptions quick;
    quick.psnr_only = true;
    gs::Expected<gs::model::EvalResult> r = gs::model::evaluate_views(trainer.model(), test_views, quick, &pool);
    if (!r.ok()) return fail(kCmd, "evaluation at iteration 0: " + r.status().to_string());
    if (gs::Status st = record_psnr(0, r->psnr); !st.ok()) return fail(kCmd, st.to_string());
  }
  int last_full = -1;
  for (int it = trainer.iteration() + 1; it <= a.iterations; ++it) {
    gs::model::IterationStats stats;
    const double t0 = gs::platform::now_seconds();
    const gs::Status st = trainer.step(&stats);
    const double dt = gs::platform::now_seconds() - t0;
    if (!st.ok()) {
      line.break_line();
      return fail(kCmd, "iteration " + std::to_string(it) + ": " + st.to_string());
    }
    progress.train_seconds += dt;
    progress.iteration_ms.push_back(float(1e3 * dt));
    line.update(stats);

    const bool full = it == a.iterations || std::binary_search(save_at->begin(), save_at->end(), it);
    gs::Status out_st;
    if (full) {
      out_st = full_eval(it, model_file_for(it));
      last_full = it;
    }
    if (a.optimize_poses && a.eval_every > 0 && it % a.eval_every == 0 && !a.quiet) {
      const gs::pose::PoseErrors e = errors_for(current_train_poses(), train_index, truth, true);
      line.break_line();
      std::fprintf(stderr, "it %d: training poses vs true: rotation mean %.3f deg (median %.3f), translation %.2f%% of radius\n", it,
                   e.rotation_mean_deg, e.rotation_median_deg, 100 * e.translation_mean_frac);
    }
    if (!full && a.eval_every > 0 && have_test && it % a.eval_every == 0) {
      gs::model::EvalOptions quick;
      quick.psnr_only = true;
      gs::Expected<gs::model::EvalResult> r = gs::model::evaluate_views(trainer.model(), test_views, quick, &pool);
      out_st = r.ok() ? record_psnr(it, r->psnr) : r.status();
    }
    if (out_st.ok() && (it == a.iterations || (a.checkpoint_every > 0 && it % a.checkpoint_every == 0)))
      out_st = checkpoint();
    if (!out_st.ok()) {
      line.break_line();
      return fail(kCmd, "iteration " + std::to_string(it) + ": " + out_st.to_string());
    }
  }
  line.break_line();

  // 4. The final model (and its evaluation when this session did not run the last iteration).
  const int final_it = trainer.iteration();
  const std::string model_path = (fs::path(a.out) / kModelFile).string();
  gs::Status final_st = last_full == final_it ? gs::Status::Ok() : full_eval(final_it, model_file_for(final_it));
  if (final_st.ok() && model_file_for(final_it) != model_path) final_st = gs::model::save_model(trainer.model(), model_path);
  if (final_st.ok() && a.optimize_poses)
    final_st = write_posed_model(a.dataset, train_names, current_train_poses(), (fs::path(a.out) / "refined_poses").string());
  if (!final_st.ok()) return fail(kCmd, final_st.to_string());

  TrainSummary s;
  s.have_pose_errors = true;
  s.train_pose_input = input_errors;
  s.train_pose_final = errors_for(current_train_poses(), train_index, truth, true);
  s.run_dir = a.out;
  s.image_features = gs::model::image_feature_mode_name(trainer.model().config.image_features);
  s.iterations = final_it;
  s.have_test_views = have_test;
  s.final_eval = final_eval;
  s.train_seconds = progress.train_seconds;
  s.median_iteration_ms = gs::median(std::vector<double>(progress.iteration_ms.begin(), progress.iteration_ms.end()));
  s.anchors = trainer.model().anchor_count;
  s.train_views = train_views.size();
  s.test_views = test_views.size();
  s.model_bytes = trainer.model().file_bytes();
  s.model_file_bytes = file_size_or_zero(model_path);
  s.isa = kernels.isa;
  s.threads = pool.num_threads();
  for (const gs::model::ViewMetrics& v : final_eval.views) s.mean_gaussians += double(v.gaussians);
  if (!final_eval.views.empty()) s.mean_gaussians /= double(final_eval.views.size());

  std::printf("hbgs train: %d iterations in %.1f s (median %.1f ms per iteration), %zu anchors, ISA %s, %d threads%s\n",
              s.iterations, s.train_seconds, s.median_iteration_ms, s.anchors, s.isa.c_str(), s.threads,
              resumed_from >= 0 ? (" (resumed at iteration " + std::to_string(resumed_from) + ")").c_str() : "");
  if (have_test) {
    std::printf("  test (%zu views): PSNR %.2f dB, SSIM %.4f", s.test_views, final_eval.psnr, final_eval.ssim);
    if (final_eval.lpips >= 0) std::printf(", %s %.4f", gs::metrics::LpipsAlex::kLabel, final_eval.lpips);
    std::printf(", %.0f Gaussians per view\n", s.mean_gaussians);
    std::printf("  results: %s/%s, %s/%s, renders in %s/test/ours_%d/renders/\n", a.out.c_str(), kResultsJson,
                a.out.c_str(), kPerViewJson, a.out.c_str(), final_it);
    if (a.eval_every > 0) std::printf("  PSNR vs time: %s/%s (.csv)\n", a.out.c_str(), kPsnrSvg);
  }
  if (a.optimize_poses || a.pose_noise != "none")
    std::printf("  training poses (Sim(3)-aligned, vs true): rotation mean %.3f deg (input %.3f), translation mean %.4f "
                "(%.2f%% of radius; input %.2f%%)%s\n",
                s.train_pose_final.rotation_mean_deg, s.train_pose_input.rotation_mean_deg, s.train_pose_final.translation_mean,
                100 * s.train_pose_final.translation_mean_frac, 100 * s.train_pose_input.translation_mean_frac,
                a.optimize_poses ? (", refined model in " + a.out + "/refined_poses/").c_str() : "");
  std::printf("  model: %s (%.2f MB)\n", model_path.c_str(), double(s.model_file_bytes) / 1e6);
  if (summary) *summary = std::move(s);
  return kExitOk;
}

Command add_train_command(CLI::App& parent) {
  auto args = std::make_shared<TrainArgs>();
  CLI::App* sub = parent.add_subcommand("train", "Train the hybrid anchor model on a COLMAP dataset");
  sub->add_option("dataset", args->dataset, "COLMAP dataset folder (images/ and sparse/0/ with points)")->required();
  sub->add_option("--out", args->out, "Run folder (model, checkpoint, results, renders)")->required();
  sub->add_option("--iterations", args->iterations, "Training iterations")->capture_default_str()->check(CLI::Range(1, 100000000));
  sub->add_option("--image-features", args->image_features, "Image-based anchor features (none: plain Scaffold-GS)")
      ->capture_default_str()
      ->check(CLI::IsMember({"paper", "none"}));
  sub->add_option("--max-anchors", args->max_anchors, "Hard budget on anchors")->capture_default_str()->check(CLI::Range(size_t(1), size_t(1) << 32));
  sub->add_option("--max-gaussians", args->max_gaussians, "Hard budget on neural Gaussians per view")
      ->capture_default_str()
      ->check(CLI::Range(size_t(1), size_t(1) << 34));
  sub->add_option("--voxel-size", args->voxel_size, "Anchor voxel size in world units (0: automatic)")
      ->capture_default_str()
      ->check(CLI::Range(0.0f, 1e9f));
  sub->add_option("--seed", args->seed, "Seed (MLP initialisation, view order)")->capture_default_str();
  sub->add_option("--threads", args->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  sub->add_option("--max-width", args->max_width, "Downscale views to at most this width (0: full size)")
      ->capture_default_str()
      ->check(CLI::Range(0, gs::io::kMaxImageSide));
  sub->add_option("--checkpoint-every", args->checkpoint_every, "Write checkpoint.bin every N iterations (0: only at the end)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000000));
  sub->add_option("--eval-every", args->eval_every, "Test PSNR into psnr_vs_time.csv/.svg every N iterations (0: never)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000000));
  sub->add_option("--save-at", args->save_at, "Iterations at which to save model_<it>.hbgs and evaluate fully (ours_<it>)")
      ->capture_default_str();
  sub->add_option("--lpips-weights", args->lpips_weights, "LPIPS-Alex weights folder (default: ../shared/data/lpips_alex if present)");
  sub->add_option("--pose-noise", args->pose_noise,
                  "Seeded noise on the input poses: none, barf:SIGMA (BARF se(3), 0.15 = hard case), rot:DEG,trans:FRAC (of the scene radius); add ,seed:N")
      ->capture_default_str();
  sub->add_option("--pose-noise-on", args->pose_noise_on, "Which poses the noise perturbs")
      ->capture_default_str()
      ->check(CLI::IsMember({"train", "test", "all"}));
  sub->add_flag("--optimize-poses", args->optimize_poses, "Optimise the training poses jointly with the scene (saved to refined_poses/)");
  sub->add_flag("!--no-point-align", args->point_align,
                "With --optimize-poses: skip the photometric alignment of the poses to the SfM points before training");
  sub->add_option("--pose-init", args->pose_init,
                  "With --optimize-poses: sfm = first reconstruct the training images with COLMAP and bring that into the "
                  "dataset's frame (Sim(3) on camera centres, then ICP onto the SfM points): for poses wrong by several degrees")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "sfm"}));
  sub->add_option("--colmap", args->colmap, "COLMAP program for --pose-init sfm")->capture_default_str();
  sub->add_option("--sfm-images", args->sfm_images,
                  "Images COLMAP sees for --pose-init sfm: auto (the dataset's largest images* copy up to 1600 px, else the "
                  "training images), train, or a folder (in the dataset or a path)")
      ->capture_default_str();
  sub->add_option("--register-passes", args->register_passes,
                  "With --optimize-poses: registration passes (every training pose registered against the current model) over the first half")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000));
  sub->add_option("--feature-refresh", args->feature_refresh,
                  "Recompute the image-based features every N iterations (-1: 250 with --optimize-poses, else 0; 0: never)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 100000000));
  sub->add_option("--coarse-levels", args->coarse_levels,
                  "Coarse-to-fine halvings over the first 30% of iterations (-1: 2 with --optimize-poses unless --pose-init sfm, else 0)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 4));
  sub->add_option("--pose-lr", args->pose_lr, "Initial pose learning rate (rad; translation x scene extent)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  sub->add_flag("--resume", args->resume, "Continue the run in --out from its checkpoint (options default to its run.json)");
  sub->add_flag("--force", args->force, "Overwrite an existing run in --out");
  sub->add_flag("-q,--quiet", args->quiet, "No progress output, only the summary");
  return {sub, [args, sub] {
            args->given.clear();
            for (const CLI::Option* o : sub->get_options())
              if (o->count() > 0 && !o->get_lnames().empty()) args->given.push_back(o->get_lnames().front());
            return run_train(*args, nullptr);
          }};
}

}  // namespace hbgs::cli
