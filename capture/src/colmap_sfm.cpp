// SPDX-License-Identifier: MIT
// COLMAP driver: each stage is one `colmap` invocation through gs::platform::run_process; the
// largest reconstruction is undistorted into the dataset. Checks happen before the slow stages
// (program present, frames present) so a user learns of a missing COLMAP in milliseconds.
#include "gs/capture/colmap_sfm.h"

#include <algorithm>
#include <deque>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "gs/io/colmap.h"
#include "gs/platform/file.h"
#include "gs/platform/process.h"

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
// not depend on the default of whichever COLMAP version is installed (Debian 12's 3.8: 0). It does
// not make a run reproducible with 3.8. Measured on the built-in scene (35 views of 256x192): the
// mapper alone gives identical poses run after run on one database (1 or 2 threads), but feature
// extraction writes a few different descriptors every run even on one thread (3 of 29760, bytes
// off by up to 255: stray data, not rounding), and exhaustive matching on one and the same database,
// one thread, gives different matches for a third of the image pairs (193 of 595). So thread
// counts and the seed cannot pin COLMAP's result down; callers that need a sound reconstruction
// must check it themselves (issue 26: the train job does not yet retry a suspect reconstruction).
constexpr const char* kColmapSeed = "0";

}  // namespace

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
  std::vector<std::string> map = {colmap, "mapper", "--database_path", db, "--image_path", frames_dir, "--output_path",
                                  sparse, "--random_seed", kColmapSeed, "--Mapper.num_threads", thread_arg(o.threads)};
  if (o.permissive_registration)
    map.insert(map.end(), {"--Mapper.abs_pose_min_num_inliers", "12", "--Mapper.abs_pose_min_inlier_ratio", "0.1"});
  if (fixed)
    map.insert(map.end(), {"--Mapper.ba_refine_focal_length", "0", "--Mapper.ba_refine_principal_point", "0",
                           "--Mapper.ba_refine_extra_params", "0"});
  GS_RETURN_IF_ERROR(run_stage(
      map,
      "mapping", log_path, progress,
      [&](const std::string& l) {
        // COLMAP prints this for every registration attempt, including retries after a failure.
        if (l.rfind("Registering image #", 0) == 0 && progress && (++registered_so_far % 10 == 0))
          progress("      " + std::to_string(registered_so_far) + " registration steps");
      },
      &rep.seconds_mapping));

  // COLMAP writes one numbered model per connected reconstruction; keep the largest.
  std::string best_model;
  size_t best_images = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(sparse, ec)) {
    if (!e.is_directory(ec)) continue;
    Expected<io::ColmapModel> m = io::read_colmap_model(e.path().string());
    if (!m.ok()) continue;
    ++rep.models;
    if (m->images.size() > best_images) {
      best_images = m->images.size();
      best_model = e.path().string();
      rep.points = int(m->points.size());
    }
  }
  rep.registered = int(best_images);
  if (report != nullptr) *report = rep;
  const int needed = std::max(o.min_registered, int(o.min_registered_fraction * rep.images + 0.999));
  if (rep.registered < needed)
    return Status(StatusCode::kInternal,
                  "COLMAP registered only " + std::to_string(rep.registered) + " of " + std::to_string(rep.images) +
                      " frames (" + std::to_string(rep.models) + " reconstruction(s); at least " +
                      std::to_string(needed) +
                      " needed). The frames may be too blurred, too similar or lack texture; see " + log_path);
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
