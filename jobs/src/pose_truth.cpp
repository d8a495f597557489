// SPDX-License-Identifier: MIT
// Pose truth, noise and errors for the jobs (see gs/jobs/pose_truth.h).
#include "gs/jobs/pose_truth.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <system_error>
#include <utility>

#include "gs/io/transforms.h"
#include "gs/io/tum.h"
#include "gs/jobs/run_folder.h"
#include "gs/platform/file.h"
#include "gs/stats.h"

#include "json_util.h"

namespace gs::jobs {

Status apply_pose_noise(io::Dataset* ds, const std::string& spec, const std::string& which, PoseTruth* truth) {
  pose::PoseNoise noise;
  if (Status st = pose::parse_pose_noise(spec, &noise); !st.ok()) return invalid_argument("--pose-noise: " + st.message());
  if (which != "train" && which != "test" && which != "all")
    return invalid_argument("--pose-noise-on: '" + which + "' is not one of train, test, all");
  truth->poses.clear();
  std::vector<Pose> train;
  for (const io::DatasetView& v : ds->views) {
    truth->poses.push_back(v.camera.pose);
    if (!v.is_test) train.push_back(v.camera.pose);
  }
  pose::scene_frame(train.data(), train.size(), truth->centre, &truth->radius);
  truth->unit = 1.0 / ds->frame.scale;
  if (noise.kind == pose::PoseNoise::kNone) return Status::Ok();
  // Each view draws its own stream (seeded by its index in the whole dataset), so which views are
  // perturbed does not change any one view's noise.
  std::vector<Pose> all = truth->poses;
  std::vector<uint8_t> eligible(all.size());
  for (size_t i = 0; i < ds->views.size(); ++i) eligible[i] = which == "all" || (which == "test") == ds->views[i].is_test;
  pose::perturb_poses(noise, truth->centre, truth->radius, all.data(), all.size(), eligible.data());
  for (size_t i = 0; i < ds->views.size(); ++i)
    if (eligible[i]) ds->views[i].camera.pose = all[i];
  return Status::Ok();
}

pose::PoseErrors errors_for(const std::vector<Pose>& estimated, const std::vector<size_t>& views,
                                const PoseTruth& truth, bool align) {
  std::vector<Pose> gt;
  for (size_t i : views) gt.push_back(truth.poses[i]);
  pose::PoseErrors e = pose::pose_errors(estimated.data(), gt.data(), gt.size(), truth.radius, align);
  if (truth.unit != 1) {  // distances in the user's units (fractions of the radius need nothing)
    e.translation_mean *= truth.unit, e.translation_median *= truth.unit, e.ate_rmse *= truth.unit;
    for (double& t : e.translation) t *= truth.unit;
  }
  return e;
}

nlohmann::json pose_errors_json(const pose::PoseErrors& e, bool per_view, const std::vector<std::string>& names) {
  nlohmann::json j = {{"views", e.count},
                      {"sim3_aligned", e.aligned},
                      {"sim3_scale", e.scale},
                      {"rotation_mean_deg", e.rotation_mean_deg},
                      {"rotation_median_deg", e.rotation_median_deg},
                      {"rotation_max_deg", e.rotation_max_deg},
                      {"translation_mean", e.translation_mean},
                      {"translation_median", e.translation_median},
                      {"translation_mean_fraction_of_radius", e.translation_mean_frac},
                      {"ate_rmse", e.ate_rmse}};
  if (per_view) {
    nlohmann::json rot = nlohmann::json::object(), tr = nlohmann::json::object();
    for (size_t i = 0; i < e.rotation_deg.size(); ++i) {
      const std::string key = i < names.size() ? names[i] : std::to_string(i);
      rot[key] = e.rotation_deg[i];
      tr[key] = e.translation[i];
    }
    j["per_view_rotation_deg"] = std::move(rot);
    j["per_view_translation"] = std::move(tr);
  }
  return j;
}

namespace {

// `path` as seen from `folder`: relative when it can be (symbolic links resolved on both sides, as
// the OS resolves a '..' when following it), else absolute.
std::string path_from(const std::string& folder, const std::string& path) {
  std::error_code ec;
  const std::filesystem::path rel = std::filesystem::relative(path, folder, ec);
  return ec || rel.empty() ? absolute_path(path) : rel.generic_string();
}

// <out_dir>/transforms.json: the views of `files` with their (replaced) poses in nerfstudio's
// layout, file_path and mask_path leading from out_dir to the dataset's own files, and the
// dataset's split as train/val/test lists (val = test: nerfstudio asks for the val list once any
// list is given).
Status write_posed_transforms(const io::DatasetFiles& files, const std::string& out_dir) {
  io::TransformsFile t;
  std::vector<std::string> train, test;
  for (const io::DatasetFileView& v : files.views) {
    io::TransformsFrame f;
    f.file_path = path_from(out_dir, v.image_path);
    if (!v.mask_path.empty()) f.mask_path = path_from(out_dir, v.mask_path);
    Expected<io::TransformsIntrinsics> intrinsics = io::transforms_intrinsics(v.camera);
    if (!intrinsics.ok()) return Status(intrinsics.status().code(), v.name + ": " + intrinsics.status().message());
    f.intrinsics = *intrinsics;
    const io::ColmapImage& im = files.model.images[v.model_image];
    io::transform_matrix_from_pose(im.qvec, im.tvec, f.transform_matrix);
    (v.is_test ? test : train).push_back(f.file_path);
    t.frames.push_back(std::move(f));
  }
  // Without test views the lists would leave nerfstudio an empty evaluation split: none then.
  if (!test.empty()) t.train_filenames = train, t.val_filenames = test, t.test_filenames = test;
  return io::write_transforms_json((std::filesystem::path(out_dir) / kPosedTransformsJson).string(), t);
}

}  // namespace

Status write_posed_model(const std::string& dataset_root, const std::vector<std::string>& names,
                         const std::vector<Pose>& poses, const std::string& out_dir, const SceneFrame& frame) {
  Expected<io::DatasetFiles> files = io::read_dataset_files(dataset_root);
  if (!files.ok()) return files.status();
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < names.size(); ++i) index[names[i]] = i;
  size_t replaced = 0;
  for (io::ColmapImage& im : files->model.images) {
    const auto it = index.find(im.name);
    if (it == index.end()) continue;
    io::pose_to_colmap(frame, poses[it->second], im.qvec, im.tvec);
    ++replaced;
  }
  if (replaced != names.size())
    return invalid_argument(dataset_root + ": " + std::to_string(names.size() - replaced) + " of the posed images are not in the dataset");
  GS_RETURN_IF_ERROR(io::write_colmap_text(files->model, out_dir));
  // A fisheye camera has no form in the transforms files hbgs writes and reads: the COLMAP model only.
  for (const io::DatasetFileView& v : files->views)
    if (io::is_fisheye_model(v.camera.model)) return Status::Ok();
  return write_posed_transforms(*files, out_dir);
}

const char* frame_status_name(FrameComparison::Status s) {
  switch (s) {
    case FrameComparison::Status::kCompared: return "compared";
    case FrameComparison::Status::kLost: return "lost";
    case FrameComparison::Status::kMissing: return "missing";
  }
  return "?";
}

namespace {

// A dataset root (with sparse/0) or a model folder.
Expected<io::ColmapModel> read_model(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::exists(std::filesystem::path(path) / "sparse" / "0", ec)) return io::read_colmap_model(path + "/sparse/0");
  return io::read_colmap_model(path);
}

// One side of a comparison: poses with their image names (COLMAP) or timestamps (TUM), in the
// file's order.
struct PoseSet {
  bool timed = false;
  std::vector<std::string> names;  // COLMAP
  std::vector<double> times;       // TUM
  std::vector<Pose> poses;
};

Expected<PoseSet> read_pose_set(const std::string& path) {
  PoseSet set;
  std::error_code ec;
  if (std::filesystem::is_regular_file(path, ec)) {
    Expected<std::vector<io::TimedPose>> tum = io::read_tum_trajectory(path);
    if (!tum.ok())
      return Status(tum.status().code(), tum.status().message() + " (a file is read as a TUM trajectory; a COLMAP model is a folder)");
    set.timed = true;
    for (const io::TimedPose& p : *tum) set.times.push_back(p.time), set.poses.push_back(p.pose);
    return set;
  }
  Expected<io::ColmapModel> model = read_model(path);
  if (!model.ok()) return model.status();
  for (const io::ColmapImage& im : model->images) {
    set.names.push_back(im.name);
    set.poses.push_back(io::pose_from_colmap(im.qvec, im.tvec));
  }
  return set;
}

// Indices of a set in sequence order: TUM by time, COLMAP by image name (stable).
std::vector<size_t> sequence_order(const PoseSet& s) {
  std::vector<size_t> order(s.poses.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return s.timed ? s.times[a] < s.times[b] : s.names[a] < s.names[b];
  });
  return order;
}

// The frames a --lost file names: timestamps and image names.
struct LostList {
  std::vector<double> times;  // sorted
  std::set<std::string> names;
  bool has_time(double t, double tolerance) const {
    const auto it = std::lower_bound(times.begin(), times.end(), t - tolerance);
    return it != times.end() && *it <= t + tolerance;
  }
};

Expected<LostList> read_lost_list(const std::string& path) {
  Expected<std::string> text = platform::read_text_file(path);
  if (!text.ok()) return text.status();
  LostList lost;
  std::istringstream in(*text);
  std::string line;
  while (std::getline(in, line)) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::string word;
    if (!(words >> word)) continue;
    char* end = nullptr;
    const double t = std::strtod(word.c_str(), &end);
    if (end && *end == '\0' && std::isfinite(t)) lost.times.push_back(t);
    else lost.names.insert(word);
  }
  std::sort(lost.times.begin(), lost.times.end());
  return lost;
}

std::string time_text(double t) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6f", t);
  return buf;
}

// RPE over pairs of frames i -> j: a[k] = (truth_i, estimate_i), b[k] = (truth_j, estimate_j); the
// estimate's translations times `scale` (the Sim(3)'s, 1 unaligned).
RelativePoseErrors relative_pose_errors(const std::vector<std::pair<const Pose*, const Pose*>>& a,
                                        const std::vector<std::pair<const Pose*, const Pose*>>& b, double scale) {
  RelativePoseErrors r;
  r.pairs = a.size();
  if (a.empty()) return r;
  std::vector<double> rot, tr;
  for (size_t k = 0; k < a.size(); ++k) {
    const Pose &ti = *a[k].first, &ei = *a[k].second, &tj = *b[k].first, &ej = *b[k].second;
    rot.push_back(pose::relative_rotation_error_deg(ti, tj, ei, ej));
    // The motion from i to j in camera i's frame: R_i (C_j - C_i); the estimate's in the truth's units.
    double cti[3], ctj[3], cei[3], cej[3], d2 = 0;
    pose::centre(ti, cti), pose::centre(tj, ctj), pose::centre(ei, cei), pose::centre(ej, cej);
    for (int r3 = 0; r3 < 3; ++r3) {
      double mt = 0, me = 0;
      for (int c = 0; c < 3; ++c) {
        mt += double(ti.R[3 * r3 + c]) * (ctj[c] - cti[c]);
        me += double(ei.R[3 * r3 + c]) * (cej[c] - cei[c]);
      }
      d2 += (scale * me - mt) * (scale * me - mt);
    }
    tr.push_back(std::sqrt(d2));
  }
  r.rotation_mean_deg = mean(rot), r.rotation_median_deg = median(rot);
  r.rotation_max_deg = *std::max_element(rot.begin(), rot.end());
  r.translation_mean = mean(tr), r.translation_median = median(tr);
  r.translation_max = *std::max_element(tr.begin(), tr.end());
  return r;
}

nlohmann::json comparison_json(const PoseComparison& c, bool aligned_asked) {
  const pose::PoseErrors& err = c.errors;
  const size_t compared = c.names.size();
  nlohmann::json j = {{"matched", compared},
                      {"aligned", err.aligned},
                      {"scale", err.scale},
                      {"scene_radius", c.scene_radius},
                      {"rotation_deg", {{"mean", err.rotation_mean_deg}, {"median", err.rotation_median_deg}, {"max", err.rotation_max_deg}}},
                      {"centre", {{"mean", err.translation_mean}, {"median", err.translation_median}, {"mean_frac", err.translation_mean_frac},
                                  {"max", c.centre_max}, {"median_frac", err.translation_median / c.scene_radius},
                                  {"max_frac", c.centre_max / c.scene_radius}}},
                      {"ate_rmse", err.ate_rmse},
                      {"relative_rotation_deg", {{"mean", c.relative_rotation_mean_deg}, {"max", c.relative_rotation_max_deg}}},
                      {"rpe", {{"pairs", c.rpe.pairs},
                               {"rotation_deg", {{"mean", c.rpe.rotation_mean_deg}, {"median", c.rpe.rotation_median_deg}, {"max", c.rpe.rotation_max_deg}}},
                               {"translation", {{"mean", c.rpe.translation_mean}, {"median", c.rpe.translation_median}, {"max", c.rpe.translation_max}}}}},
                      {"matching", c.matching},
                      {"alignment", aligned_asked ? "sim3" : "none"},
                      {"truth_poses", c.truth_images},
                      {"estimate_poses", c.estimate_images},
                      {"lost", c.lost},
                      {"missing", c.missing},
                      {"missing_listed_lost", c.missing_listed_lost},
                      {"unmatched", c.unmatched},
                      {"per_image", nlohmann::json::array()},
                      {"per_frame", nlohmann::json::array()}};
  if (c.matching == "time") j["time_tolerance_s"] = c.time_tolerance;
  for (size_t i = 0; i < compared; ++i)
    j["per_image"].push_back({{"name", c.names[i]}, {"rotation_deg", err.rotation_deg[i]}, {"centre", err.translation[i]}});
  for (const FrameComparison& f : c.frames) {
    nlohmann::json row = {{"status", frame_status_name(f.status)}};
    if (f.time >= 0) row["time"] = f.time;
    else row["name"] = f.name;
    if (f.status == FrameComparison::Status::kCompared)
      row["rotation_deg"] = f.rotation_deg, row["centre"] = f.centre, row["centre_frac"] = f.centre_frac;
    j["per_frame"].push_back(std::move(row));
  }
  return j;
}

std::string per_frame_csv(const PoseComparison& c) {
  std::string s = "index,name,time,status,rotation_deg,centre_error,centre_error_frac\n";
  char buf[160];
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const FrameComparison& f = c.frames[i];
    s += std::to_string(i) + "," + f.name + "," + (f.time >= 0 ? time_text(f.time) : std::string()) + "," +
         frame_status_name(f.status) + ",";
    if (f.status == FrameComparison::Status::kCompared) {
      std::snprintf(buf, sizeof buf, "%.9g,%.9g,%.9g", f.rotation_deg, f.centre, f.centre_frac);
      s += buf;
    } else {
      s += ",,";
    }
    s += "\n";
  }
  return s;
}

}  // namespace

Expected<PoseComparison> compare_poses(const std::string& truth_path, const std::string& estimate_path,
                                       const PoseCompareOptions& opt) {
  Expected<PoseSet> truth = read_pose_set(truth_path);
  if (!truth.ok()) return truth.status();
  Expected<PoseSet> est = read_pose_set(estimate_path);
  if (!est.ok()) return est.status();
  if (truth->timed != est->timed && !opt.by_order)
    return invalid_argument(std::string("the ") + (truth->timed ? "truth" : "estimate") + " is a TUM trajectory and the " +
                            (truth->timed ? "estimate" : "truth") +
                            " a COLMAP model: only one side has timestamps; pass --by-order to pair the poses in order "
                            "(TUM by time, COLMAP by image name) or compare two TUM files");
  if (!(opt.radius >= 0) || !std::isfinite(opt.radius)) return invalid_argument("the radius must be finite and >= 0 (0: the true centres')");
  LostList lost;
  if (!opt.lost_path.empty()) {
    Expected<LostList> l = read_lost_list(opt.lost_path);
    if (!l.ok()) return l.status();
    lost = std::move(*l);
  }

  PoseComparison c;
  c.truth_images = truth->poses.size();
  c.estimate_images = est->poses.size();
  const std::vector<size_t> truth_seq = sequence_order(*truth);
  // Half the median interval of the timed side's frames (the truth's when both are): how far a
  // timestamp may be from a frame's and still name it.
  {
    const PoseSet& timed = truth->timed ? *truth : *est;
    std::vector<double> gaps;
    if (timed.timed) {
      const std::vector<size_t> seq = sequence_order(timed);
      for (size_t k = 1; k < seq.size(); ++k) gaps.push_back(timed.times[seq[k]] - timed.times[seq[k - 1]]);
    }
    c.time_tolerance = 0.5 * median(gaps);
  }
  // est_of[k]: the estimate pose matched to the k-th true frame of the sequence, or -1.
  std::vector<long> est_of(truth_seq.size(), -1);
  if (opt.by_order) {
    c.matching = "order";
    if (truth->poses.size() != est->poses.size())
      return invalid_argument("--by-order pairs the poses in order and needs as many on both sides: the truth has " +
                              std::to_string(truth->poses.size()) + ", the estimate " + std::to_string(est->poses.size()));
    const std::vector<size_t> est_seq = sequence_order(*est);
    for (size_t k = 0; k < truth_seq.size(); ++k) est_of[k] = long(est_seq[k]);
  } else if (truth->timed) {
    c.matching = "time";
    std::vector<double> times;
    for (size_t k : truth_seq) times.push_back(truth->times[k]);
    for (size_t e = 0; e < est->poses.size(); ++e) {
      const double t = est->times[e];
      const size_t hi = size_t(std::lower_bound(times.begin(), times.end(), t) - times.begin());
      size_t best = hi;
      if (hi == times.size() || (hi > 0 && t - times[hi - 1] <= times[hi] - t)) best = hi - 1;
      if (times.empty() || std::fabs(times[best] - t) > c.time_tolerance * (1 + 1e-9) || est_of[best] >= 0) {
        ++c.unmatched;
        continue;
      }
      est_of[best] = long(e);
    }
  } else {
    c.matching = "name";
    std::map<std::string, size_t> position;
    for (size_t k = 0; k < truth_seq.size(); ++k) position[truth->names[truth_seq[k]]] = k;
    for (size_t e = 0; e < est->poses.size(); ++e) {
      auto it = position.find(est->names[e]);
      if (it == position.end() || est_of[it->second] >= 0) {
        ++c.unmatched;
        continue;
      }
      est_of[it->second] = long(e);
    }
  }
  // Lost frames, and the comparison order: the estimate's for names (as this command always did),
  // the sequence's otherwise.
  const auto listed_lost = [&](size_t k) {
    const size_t ti = truth_seq[k];
    const long e = est_of[k];
    const double tolerance = std::max(c.time_tolerance, 1e-6);
    if (truth->timed && lost.has_time(truth->times[ti], tolerance)) return true;
    if (e >= 0 && est->timed && lost.has_time(est->times[size_t(e)], tolerance)) return true;
    if (!truth->timed && lost.names.count(truth->names[ti])) return true;
    return e >= 0 && !est->timed && lost.names.count(est->names[size_t(e)]) > 0;
  };
  c.frames.resize(truth_seq.size());
  std::vector<long> compared_at(truth_seq.size(), -1);  // position of a true frame in the comparison
  std::vector<size_t> seq_of_compared;                  // comparison position -> sequence index
  for (size_t k = 0; k < truth_seq.size(); ++k) {
    FrameComparison& f = c.frames[k];
    const size_t ti = truth_seq[k];
    if (truth->timed) f.time = truth->times[ti];
    else f.name = truth->names[ti];
    const bool is_lost = listed_lost(k);
    if (est_of[k] < 0) {
      ++c.missing;
      if (is_lost) ++c.missing_listed_lost;
      f.status = FrameComparison::Status::kMissing;
    } else if (is_lost) {
      ++c.lost;
      f.status = FrameComparison::Status::kLost;
    } else {
      f.status = FrameComparison::Status::kCompared;
    }
  }
  if (c.matching == "name") {
    std::vector<long> seq_of_est(est->poses.size(), -1);
    for (size_t k = 0; k < truth_seq.size(); ++k)
      if (est_of[k] >= 0) seq_of_est[size_t(est_of[k])] = long(k);
    for (size_t e = 0; e < est->poses.size(); ++e)
      if (seq_of_est[e] >= 0 && c.frames[size_t(seq_of_est[e])].status == FrameComparison::Status::kCompared)
        seq_of_compared.push_back(size_t(seq_of_est[e]));
  } else {
    for (size_t k = 0; k < truth_seq.size(); ++k)
      if (c.frames[k].status == FrameComparison::Status::kCompared) seq_of_compared.push_back(k);
  }
  std::vector<Pose> t, e;
  for (size_t pos = 0; pos < seq_of_compared.size(); ++pos) {
    const size_t k = seq_of_compared[pos];
    compared_at[k] = long(pos);
    t.push_back(truth->poses[truth_seq[k]]);
    e.push_back(est->poses[size_t(est_of[k])]);
    c.names.push_back(truth->timed ? time_text(truth->times[truth_seq[k]]) : truth->names[truth_seq[k]]);
  }
  if (t.size() < 3 && c.matching == "name" && c.lost == 0)
    return invalid_argument("only " + std::to_string(t.size()) + " images are in both models (matched by name); at least 3 are needed");
  if (t.size() < 3)
    return invalid_argument("only " + std::to_string(t.size()) + " poses are compared (matched by " + c.matching +
                            (c.lost > 0 ? ", lost ones left out" : "") + "); at least 3 are needed");
  double centre[3];
  pose::scene_frame(t.data(), t.size(), centre, &c.scene_radius);
  if (opt.radius > 0) c.scene_radius = opt.radius;
  c.errors = pose::pose_errors(e.data(), t.data(), t.size(), c.scene_radius, opt.align);
  c.centre_max = *std::max_element(c.errors.translation.begin(), c.errors.translation.end());
  std::vector<double> relative;
  for (size_t i = 1; i < t.size(); ++i) relative.push_back(pose::relative_rotation_error_deg(t[i - 1], t[i], e[i - 1], e[i]));
  c.relative_rotation_mean_deg = mean(relative);
  c.relative_rotation_max_deg = relative.empty() ? 0.0 : *std::max_element(relative.begin(), relative.end());
  // Per frame, and RPE over consecutive true frames both compared.
  std::vector<std::pair<const Pose*, const Pose*>> first, second;
  for (size_t k = 0; k < truth_seq.size(); ++k) {
    if (compared_at[k] < 0) continue;
    FrameComparison& f = c.frames[k];
    const size_t pos = size_t(compared_at[k]);
    f.rotation_deg = c.errors.rotation_deg[pos];
    f.centre = c.errors.translation[pos];
    f.centre_frac = f.centre / c.scene_radius;
    if (k + 1 < truth_seq.size() && compared_at[k + 1] >= 0) {
      const size_t next = size_t(compared_at[k + 1]);
      first.emplace_back(&t[pos], &e[pos]);
      second.emplace_back(&t[next], &e[next]);
    }
  }
  c.rpe = relative_pose_errors(first, second, c.errors.scale);
  if (!opt.json_path.empty())
    GS_RETURN_IF_ERROR(platform::write_file_atomic(opt.json_path, comparison_json(c, opt.align).dump(2) + "\n"));
  if (!opt.per_frame_csv.empty()) GS_RETURN_IF_ERROR(platform::write_file_atomic(opt.per_frame_csv, per_frame_csv(c)));
  return c;
}

Expected<PoseComparison> compare_pose_models(const std::string& truth, const std::string& estimate, const std::string& json_path) {
  PoseCompareOptions options;
  options.json_path = json_path;
  return compare_poses(truth, estimate, options);
}

}  // namespace gs::jobs
