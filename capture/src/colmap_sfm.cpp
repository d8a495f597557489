// SPDX-License-Identifier: MIT
// COLMAP driver: each stage is one `colmap` invocation through gs::platform::run_process; the
// largest reconstruction is undistorted into the dataset. Checks happen before the slow stages
// (program present, frames present) so a user learns of a missing COLMAP in milliseconds.
#include "gs/capture/colmap_sfm.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <map>
#include <string>
#include <system_error>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/process.h"
#include "gs/pose/pose.h"
#include "gs/stats.h"

namespace gs::capture {
namespace fs = std::filesystem;
namespace {

bool is_image_name(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg";
}

int count_images(const std::string& dir) {
  std::error_code ec;
  int n = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(dir, ec))
    if (e.is_regular_file(ec) && is_image_name(e.path())) ++n;
  return n;
}

// Runs one stage, keeping the last output lines for the error message.
Status run_stage(const std::vector<std::string>& argv, const std::string& stage, const std::string& log_path,
                 const ProgressFn& progress, const std::function<void(const std::string&)>& on_line, double* seconds) {
  std::deque<std::string> tail;
  auto keep = [&](const std::string& line) {
    tail.push_back(line);
    if (tail.size() > 8) tail.pop_front();
    if (on_line) on_line(line);
  };
  Expected<platform::ProcessResult> r = platform::run_process(argv, log_path, keep);
  if (!r.ok()) return r.status();
  *seconds = r->seconds;
  if (r->exit_code != 0) {
    std::string msg = "COLMAP " + stage + " failed (exit code " + std::to_string(r->exit_code) + "); full output in " +
                      log_path + "; last lines:";
    for (const std::string& l : tail) msg += "\n  " + l;
    return Status(StatusCode::kInternal, msg);
  }
  if (progress) progress("      " + stage + " done in " + std::to_string(int(r->seconds + 0.5)) + " s");
  return Status::Ok();
}

std::string thread_arg(int threads) { return std::to_string(threads > 0 ? threads : -1); }

// COLMAP's seed for its random sampling (RANSAC, initial pair trials), given explicitly so a run does
// not depend on the default of whichever COLMAP version is installed (Debian 12's 3.8: 0). With it
// the mapper repeats exactly on one database (byte-identical images.bin on 1 or 2 threads), but
// extraction and matching do not repeat, on any thread count: see the header and docs/CAPTURE.md.
constexpr const char* kColmapSeed = "0";

// Camera centres of two reconstructions agree within this fraction of the scene radius when both
// are sound (measured on the built-in scene: at most 2.8 % after the Sim(3)); the alignment of a
// check run is fitted on the views that agree this well.
constexpr double kAlignTolerance = 0.05;

// The largest reconstruction under `sparse` (COLMAP writes one numbered model per connected
// reconstruction): its folder, or "" when there is none. *models counts the readable ones.
std::string largest_model(const std::string& sparse, int* models, io::ColmapModel* model) {
  std::error_code ec;
  std::string best;
  size_t best_images = 0;
  std::vector<fs::path> dirs;
  for (const fs::directory_entry& e : fs::directory_iterator(sparse, ec))
    if (e.is_directory(ec)) dirs.push_back(e.path());
  std::sort(dirs.begin(), dirs.end());  // a tie goes to the lowest number, whatever the listing order
  for (const fs::path& d : dirs) {
    Expected<io::ColmapModel> m = io::read_colmap_model(d.string());
    if (!m.ok()) continue;
    if (models != nullptr) ++*models;
    if (m->images.size() > best_images) {
      best_images = m->images.size();
      best = d.string();
      if (model != nullptr) *model = std::move(m).value();
    }
  }
  return best;
}

std::vector<std::string> mapper_args(const std::string& colmap, const std::string& db, const std::string& frames_dir,
                                     const std::string& out, const std::string& seed, const ColmapOptions& o) {
  std::vector<std::string> map = {colmap, "mapper", "--database_path", db, "--image_path", frames_dir, "--output_path",
                                  out, "--random_seed", seed, "--Mapper.num_threads", thread_arg(o.threads)};
  if (o.permissive_registration)
    map.insert(map.end(), {"--Mapper.abs_pose_min_num_inliers", "12", "--Mapper.abs_pose_min_inlier_ratio", "0.1"});
  if (!o.camera_params.empty())
    map.insert(map.end(), {"--Mapper.ba_refine_focal_length", "0", "--Mapper.ba_refine_principal_point", "0",
                           "--Mapper.ba_refine_extra_params", "0"});
  return map;
}

double distance(const double a[3], const double b[3]) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

// How many of the n pairs y ~ T(x) agree within `tolerance`; *weight gets 1 for those, 0 for the others.
size_t count_inliers(const pose::Sim3& T, const double* x, const double* y, size_t n, double tolerance, std::vector<double>* weight) {
  size_t count = 0;
  weight->assign(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    double m[3];
    pose::transform_point(T, x + 3 * i, m);
    if (distance(m, y + 3 * i) <= tolerance) (*weight)[i] = 1, ++count;
  }
  return count;
}

// y ~ T(x) over camera centres, robust to up to half of the pairs being anywhere (a corrupted
// reconstruction can misplace several views together, which tilts a trimmed least-squares fit):
// the Sim(3) of the 3-view subset that the most pairs agree with (within `tolerance`), refitted
// on those pairs twice. Subsets: all of them up to 20 views, else 600 drawn by a fixed sequence,
// so the result does not change from run to run. False when no subset gives a Sim(3).
bool align_centres(const std::vector<double>& x, const std::vector<double>& y, double tolerance, pose::Sim3* out) {
  const size_t n = x.size() / 3;
  if (n < 3) return false;
  std::vector<std::array<size_t, 3>> subsets;
  if (n <= 20) {
    for (size_t a = 0; a < n; ++a)
      for (size_t b = a + 1; b < n; ++b)
        for (size_t c = b + 1; c < n; ++c) subsets.push_back({a, b, c});
  } else {
    uint64_t state = 0x9E3779B97F4A7C15ull;
    auto next = [&] {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      return size_t((state >> 33) % n);
    };
    while (subsets.size() < 600) {
      const std::array<size_t, 3> s = {next(), next(), next()};
      if (s[0] != s[1] && s[1] != s[2] && s[0] != s[2]) subsets.push_back(s);
    }
  }
  size_t best = 0;
  std::vector<double> weight;
  for (const std::array<size_t, 3>& s : subsets) {
    double xs[9], ys[9];
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) xs[3 * k + d] = x[3 * s[k] + d], ys[3 * k + d] = y[3 * s[k] + d];
    pose::Sim3 T;
    if (!pose::fit_sim3(xs, ys, nullptr, 3, &T)) continue;
    const size_t agree = count_inliers(T, x.data(), y.data(), n, tolerance, &weight);
    if (agree > best) best = agree, *out = T;
  }
  if (best < 3) return false;
  for (int round = 0; round < 2; ++round) {
    count_inliers(*out, x.data(), y.data(), n, tolerance, &weight);
    pose::Sim3 refined;
    if (!pose::fit_sim3(x.data(), y.data(), weight.data(), n, &refined)) break;
    *out = refined;
  }
  return true;
}

}  // namespace

std::vector<std::string> SfmConsistency::suspect_names() const {
  std::vector<std::string> out;
  for (const ViewAgreement& v : views)
    if (v.suspect) out.push_back(v.name);
  return out;
}

namespace {
// compare_reconstructions on the check runs in place (choose_most_consistent compares each run with
// all the others without copying models).
SfmConsistency compare_to_runs(const io::ColmapModel& chosen, const std::vector<const io::ColmapModel*>& checks,
                               double suspect_rotation_deg, double suspect_centre_fraction) {
  SfmConsistency c;
  c.check_runs = int(checks.size());
  std::map<std::string, size_t> index;  // name -> row of c.views
  for (const io::ColmapImage& im : chosen.images) index.emplace(im.name, 0);
  for (auto& [name, row] : index) {
    row = c.views.size();
    c.views.push_back(ViewAgreement{name});
  }
  std::vector<Pose> poses(c.views.size());
  for (const io::ColmapImage& im : chosen.images) poses[index[im.name]] = io::pose_from_colmap(im.qvec, im.tvec);
  double scene_centre[3], radius = 1;
  pose::scene_frame(poses.data(), poses.size(), scene_centre, &radius);

  for (const io::ColmapModel* check_run : checks) {
    const io::ColmapModel& check = *check_run;
    std::vector<size_t> rows;
    std::vector<Pose> other;
    std::vector<double> x, y;  // centres: check run, chosen
    for (const io::ColmapImage& im : check.images) {
      auto it = index.find(im.name);
      if (it == index.end()) continue;
      rows.push_back(it->second);
      other.push_back(io::pose_from_colmap(im.qvec, im.tvec));
      double a[3], b[3];
      pose::centre(other.back(), a);
      pose::centre(poses[it->second], b);
      x.insert(x.end(), a, a + 3);
      y.insert(y.end(), b, b + 3);
    }
    pose::Sim3 to_chosen;
    if (!align_centres(x, y, kAlignTolerance * radius, &to_chosen)) continue;
    ++c.aligned_runs;
    for (size_t k = 0; k < rows.size(); ++k) {
      ViewAgreement& v = c.views[rows[k]];
      const Pose aligned = pose::transform_pose(to_chosen, other[k]);
      const double rot = pose::rotation_error_deg(aligned, poses[rows[k]]);
      double a[3], b[3];
      pose::centre(aligned, a);
      pose::centre(poses[rows[k]], b);
      const double centre = distance(a, b) / radius;
      ++v.check_runs;
      v.rotation_deg = std::max(v.rotation_deg, rot);
      v.centre_fraction = std::max(v.centre_fraction, centre);
      if (rot > suspect_rotation_deg || centre > suspect_centre_fraction) ++v.disagreeing;
    }
  }
  std::vector<double> rotations;
  for (ViewAgreement& v : c.views) {
    v.suspect = v.disagreeing > 0 && 2 * v.disagreeing >= v.check_runs;
    c.suspect += v.suspect;
    if (v.check_runs > 0) rotations.push_back(v.rotation_deg);
    c.rotation_max_deg = std::max(c.rotation_max_deg, v.rotation_deg);
  }
  c.rotation_median_deg = upper_median_in_place(rotations);
  return c;
}

}  // namespace

SfmConsistency compare_reconstructions(const io::ColmapModel& chosen, const std::vector<io::ColmapModel>& checks,
                                       double suspect_rotation_deg, double suspect_centre_fraction) {
  std::vector<const io::ColmapModel*> runs;
  for (const io::ColmapModel& m : checks) runs.push_back(&m);
  return compare_to_runs(chosen, runs, suspect_rotation_deg, suspect_centre_fraction);
}

size_t choose_most_consistent(const std::vector<io::ColmapModel>& runs, size_t min_registered, double suspect_rotation_deg,
                              double suspect_centre_fraction, SfmConsistency* consistency, int* first_suspect) {
  size_t best = 0;
  bool have = false;
  for (size_t i = 0; i < runs.size(); ++i) {
    if (runs[i].images.size() < min_registered && i > 0) continue;
    std::vector<const io::ColmapModel*> others;
    for (size_t j = 0; j < runs.size(); ++j)
      if (j != i) others.push_back(&runs[j]);
    SfmConsistency c = compare_to_runs(runs[i], others, suspect_rotation_deg, suspect_centre_fraction);
    if (i == 0 && first_suspect) *first_suspect = c.suspect;
    const bool better = !have || c.suspect < consistency->suspect ||
                        (c.suspect == consistency->suspect && runs[i].images.size() > runs[best].images.size());
    if (better) best = i, have = true, *consistency = std::move(c);
  }
  return best;
}

Expected<Matcher> parse_matcher(const std::string& name) {
  if (name == "sequential") return Matcher::kSequential;
  if (name == "exhaustive") return Matcher::kExhaustive;
  return invalid_argument("unknown matcher '" + name + "' (sequential or exhaustive)");
}

Status check_colmap(const ColmapOptions& o) {
  if (!platform::find_program(o.colmap).empty()) return Status::Ok();
  return Status(StatusCode::kUnsupported,
                "COLMAP not found: '" + o.colmap +
                    "' is not an executable on PATH. Install it (Debian/Ubuntu: sudo apt install colmap) or pass "
                    "--colmap /path/to/colmap");
}

Status run_colmap_reconstruction(const std::string& frames_dir, const std::string& work_dir, const std::string& log_path,
                                 const ColmapOptions& o, const ProgressFn& progress, ColmapReport* report,
                                 std::string* model_dir) {
  ColmapReport rep;
  GS_RETURN_IF_ERROR(check_colmap(o));
  const std::string colmap = platform::find_program(o.colmap);
  rep.images = count_images(frames_dir);
  if (rep.images < 2)
    return invalid_argument("structure from motion needs at least 2 frames; " + frames_dir + " has " +
                            std::to_string(rep.images));
  GS_RETURN_IF_ERROR(platform::make_dirs(work_dir));
  const std::string db = work_dir + "/database.db", sparse = work_dir + "/sparse";
  std::error_code ec;
  fs::remove(db, ec);
  fs::remove_all(sparse, ec);
  GS_RETURN_IF_ERROR(platform::make_dirs(sparse));

  int extracted = 0;
  if (progress) progress("[1/4] COLMAP feature extraction on " + std::to_string(rep.images) + " frames (CPU SIFT)");
  std::vector<std::string> extract = {
      colmap, "feature_extractor", "--database_path", db, "--image_path", frames_dir, "--random_seed", kColmapSeed, "--ImageReader.single_camera", "1",
      "--ImageReader.camera_model", o.camera_model, "--SiftExtraction.use_gpu", "0", "--SiftExtraction.num_threads",
      thread_arg(o.threads), "--SiftExtraction.max_image_size", std::to_string(o.max_image_size)};
  const bool fixed = !o.camera_params.empty();
  if (fixed) extract.insert(extract.end(), {"--ImageReader.camera_params", o.camera_params});
  GS_RETURN_IF_ERROR(run_stage(
      extract,
      "feature extraction", log_path, progress,
      [&](const std::string& l) {
        if (l.find("Processed file") != std::string::npos && progress && (++extracted % 20 == 0))
          progress("      " + std::to_string(extracted) + "/" + std::to_string(rep.images) + " frames");
      },
      &rep.seconds_features));

  const bool sequential = o.matcher == Matcher::kSequential;
  if (progress) progress(std::string("[2/4] COLMAP matching (") + (sequential ? "sequential" : "exhaustive") + ")");
  std::vector<std::string> match = {colmap, sequential ? "sequential_matcher" : "exhaustive_matcher", "--database_path",
                                    db, "--random_seed", kColmapSeed, "--SiftMatching.use_gpu", "0", "--SiftMatching.num_threads",
                                    thread_arg(o.threads)};
  GS_RETURN_IF_ERROR(run_stage(match, "matching", log_path, progress, {}, &rep.seconds_matching));

  int registered_so_far = 0;
  if (progress) progress("[3/4] COLMAP mapping");
  GS_RETURN_IF_ERROR(run_stage(
      mapper_args(colmap, db, frames_dir, sparse, kColmapSeed, o),
      "mapping", log_path, progress,
      [&](const std::string& l) {
        // COLMAP prints this for every registration attempt, including retries after a failure.
        if (l.rfind("Registering image #", 0) == 0 && progress && (++registered_so_far % 10 == 0))
          progress("      " + std::to_string(registered_so_far) + " registration steps");
      },
      &rep.seconds_mapping));

  io::ColmapModel chosen;
  std::string best_model = largest_model(sparse, &rep.models, &chosen);
  rep.registered = int(chosen.images.size());
  rep.points = int(chosen.points.size());
  const int needed = std::max(o.min_registered, int(o.min_registered_fraction * rep.images + 0.999));
  if (rep.registered < needed) {
    if (report != nullptr) *report = rep;
    return Status(StatusCode::kInternal,
                  "COLMAP registered only " + std::to_string(rep.registered) + " of " + std::to_string(rep.images) +
                      " frames (" + std::to_string(rep.models) + " reconstruction(s); at least " +
                      std::to_string(needed) +
                      " needed). The frames may be too blurred, too similar or lack texture; see " + log_path);
  }

  // The consistency check: the same database mapped again with other seeds.
  if (o.check_runs > 0) {
    const double t0 = platform::now_seconds();
    if (progress)
      progress("      consistency check: mapping again with " + std::to_string(o.check_runs) + " other seed(s)");
    // runs[0] is the first mapping; each check run that reconstructed something follows, with its
    // seed and model folder.
    std::vector<io::ColmapModel> runs;
    std::vector<int> seeds = {0};
    std::vector<std::string> dirs = {best_model};
    runs.push_back(chosen);
    for (int seed = 1; seed <= o.check_runs; ++seed) {
      const std::string out = work_dir + "/sparse_check" + std::to_string(seed);
      fs::remove_all(out, ec);
      GS_RETURN_IF_ERROR(platform::make_dirs(out));
      double seconds = 0;
      GS_RETURN_IF_ERROR(run_stage(mapper_args(colmap, db, frames_dir, out, std::to_string(seed), o),
                                   "check mapping (seed " + std::to_string(seed) + ")", log_path, {}, {}, &seconds));
      io::ColmapModel m;
      const std::string dir = largest_model(out, nullptr, &m);
      if (dir.empty()) continue;
      runs.push_back(std::move(m));
      seeds.push_back(seed);
      dirs.push_back(dir);
    }
    const size_t pick = choose_most_consistent(runs, size_t(needed), o.suspect_rotation_deg, o.suspect_centre_fraction,
                                               &rep.consistency, &rep.first_run_suspect);
    if (pick != 0) {
      chosen = std::move(runs[pick]);
      best_model = dirs[pick];
      rep.chosen_seed = seeds[pick];
      rep.registered = int(chosen.images.size());
      rep.points = int(chosen.points.size());
    }
    rep.consistency.check_runs = o.check_runs;  // a run that reconstructed nothing counts too
    rep.consistency.seconds = platform::now_seconds() - t0;
    if (progress) {
      const SfmConsistency& c = rep.consistency;
      char line[256];
      if (rep.chosen_seed != 0) {
        std::snprintf(line, sizeof line, "      consistency check: the first mapping had %d suspect view(s); the run of seed %d agrees with the others best and is used",
                      rep.first_run_suspect, rep.chosen_seed);
        progress(line);
      }
      std::snprintf(line, sizeof line, "      consistency check: %d suspect view(s) of %d; the runs agree to %.2f deg (median), %.2f (max) in %.0f s",
                    c.suspect, rep.registered, c.rotation_median_deg, c.rotation_max_deg, c.seconds);
      progress(line);
      for (const ViewAgreement& v : c.views) {
        if (!v.suspect) continue;
        std::snprintf(line, sizeof line, "        suspect: %s, %.1f deg and %.1f %% of the radius apart in %d of %d check run(s)",
                      v.name.c_str(), v.rotation_deg, 100 * v.centre_fraction, v.disagreeing, v.check_runs);
        progress(line);
      }
    }
  }
  if (report != nullptr) *report = rep;
  *model_dir = best_model;
  return Status::Ok();
}

bool is_fisheye_model_name(const std::string& model) { return io::is_fisheye_model(model); }

namespace {

// A fisheye reconstruction as the dataset: COLMAP's model (binary) and its registered frames as
// they are. COLMAP's image_undistorter would pick the pinhole's field of view from the image's
// border, which for a lens of 180 degrees or more lies at or beyond 90 degrees from the axis.
Status write_distorted_dataset(const std::string& frames_dir, const std::string& model_dir, const std::string& dataset_dir) {
  Expected<io::ColmapModel> model = io::read_colmap_binary(model_dir);
  if (!model.ok()) return model.status();
  GS_RETURN_IF_ERROR(platform::make_dirs(dataset_dir + "/images"));
  GS_RETURN_IF_ERROR(platform::make_dirs(dataset_dir + "/sparse/0"));
  std::error_code ec;
  for (const io::ColmapImage& im : model->images) {
    fs::copy_file(frames_dir + "/" + im.name, dataset_dir + "/images/" + im.name, fs::copy_options::overwrite_existing, ec);
    if (ec) return io_error("cannot copy " + frames_dir + "/" + im.name + " into the dataset: " + ec.message());
  }
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) {
    fs::copy_file(model_dir + "/" + f, dataset_dir + "/sparse/0/" + f, fs::copy_options::overwrite_existing, ec);
    if (ec) return io_error("cannot copy " + model_dir + "/" + f + " into the dataset: " + ec.message());
  }
  return Status::Ok();
}

}  // namespace

Status run_colmap_sfm(const std::string& frames_dir, const std::string& work_dir, const std::string& dataset_dir,
                      const std::string& log_path, const ColmapOptions& o, const ProgressFn& progress,
                      ColmapReport* report) {
  ColmapReport local;
  ColmapReport& rep = report != nullptr ? *report : local;
  std::string best_model;
  GS_RETURN_IF_ERROR(run_colmap_reconstruction(frames_dir, work_dir, log_path, o, progress, &rep, &best_model));
  const std::string colmap = platform::find_program(o.colmap);
  std::error_code ec;

  if (is_fisheye_model_name(o.camera_model)) {
    if (progress)
      progress("[4/4] writing " + std::to_string(rep.registered) + " registered " + o.camera_model +
               " frames as they are (hbgs undistorts them on load)");
    return write_distorted_dataset(frames_dir, best_model, dataset_dir);
  }
  if (progress)
    progress("[4/4] undistorting " + std::to_string(rep.registered) + " registered frames to PINHOLE");
  const std::string undist = work_dir + "/undistorted";
  fs::remove_all(undist, ec);
  GS_RETURN_IF_ERROR(run_stage({colmap, "image_undistorter", "--image_path", frames_dir, "--input_path", best_model,
                                "--output_path", undist, "--output_type", "COLMAP"},
                               "undistortion", log_path, progress, {}, &rep.seconds_undistort));

  // image_undistorter writes <undist>/images and <undist>/sparse/*.bin; hbgs reads sparse/0.
  GS_RETURN_IF_ERROR(platform::make_dirs(dataset_dir + "/sparse"));
  fs::rename(undist + "/images", dataset_dir + "/images", ec);
  if (ec) return io_error("cannot move " + undist + "/images to " + dataset_dir + "/images: " + ec.message());
  fs::create_directories(dataset_dir + "/sparse/0", ec);
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) {
    fs::rename(undist + "/sparse/" + f, dataset_dir + "/sparse/0/" + f, ec);
    if (ec) return io_error("COLMAP's undistorted model has no " + std::string(f) + " (" + ec.message() + ")");
  }
  return Status::Ok();
}

}  // namespace gs::capture
