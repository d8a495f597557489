// SPDX-License-Identifier: MIT
// Private to the training job: the prepared session's state (TrainSession::Impl), shared by
// train_session.cpp (creating it), train_pose_stages.cpp (the pose stages: SfM initialisation,
// point alignment, test views in the model's frame) and train_run.cpp (the run folder around it),
// and the small helpers they all use.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/jobs/pose_truth.h"
#include "gs/jobs/train.h"
#include "gs/model/point_alignment.h"
#include "gs/model/trainer.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "gs/simd/kernel_table.h"

namespace gs::jobs {

struct TrainSession::Impl {
  TrainRunOptions options;
  io::Dataset dataset;
  PoseTruth truth;
  std::vector<const io::DatasetView*> train_views, test_views;
  std::vector<size_t> train_index;  // dataset index of each training view
  std::vector<std::string> train_names;
  pose::PoseErrors input_errors;
  nlohmann::json sfm_init, point_alignment;  // stage reports for results.json
  std::vector<uint8_t> sfm_registered;       // [training views] 1 where SfM registered the view
  std::vector<uint8_t> sfm_suspect;          // [training views] 1 where SfM's consistency check doubts it
  // Training view i is held back by what SfM said: not registered, or doubted by its check.
  bool held_by_sfm(size_t i) const {
    return i < sfm_registered.size() && (!sfm_registered[i] || (i < sfm_suspect.size() && sfm_suspect[i]));
  }
  // [training views] 1 where the point alignment moved the view over 3x the median move (it was
  // put back at its start pose): a pose in doubt, held back with the view check's suspects (empty
  // when the check is off or the alignment did not run).
  std::vector<uint8_t> alignment_doubted;
  nlohmann::json view_check;                 // the point-agreement check's report for results.json
  std::vector<uint8_t> suspect;              // [training views] 1 where the points say the pose is wrong
  pose::TypicalAgreement typical_agreement;  // of the training views at their start poses
  std::unique_ptr<platform::ThreadPool> pool;
  const simd::KernelTable* kernels = nullptr;
  std::unique_ptr<model::Trainer> trainer;

  // Frees the training views' pixels (photos, masks, valid maps) for a finished run's final
  // evaluation, which reads the test views only: snowmiku_plush's 84 training photos are 29 MB,
  // which the evaluation's own buffers came on top of. The trainer must not step or register after.
  void release_training_pixels() {
    for (io::DatasetView& v : dataset.views) {
      if (v.is_test) continue;
      for (io::Image8* img : {&v.image, &v.mask, &v.valid}) std::vector<uint8_t>().swap(img->pixels);
    }
  }
  pose::PoseErrors errors(const std::vector<Pose>& now, bool align) const { return errors_for(now, train_index, truth, align); }
  // With optimised poses the model lives in the frame the training poses ended in, which can move
  // away from the dataset's (SfM re-initialisation, the mean of the pose noise, the small gauge
  // freedoms of joint optimisation): at the dataset poses a test PSNR mixes that offset into the
  // model's error. So test views are evaluated as BARF and the paper do: their dataset poses mapped
  // into the model's frame by the Sim(3) fitted on the training camera centres (true -> now, views
  // still held back left out, outliers trimmed), then registered against the model
  // (register_test_views). Returns copies of the test views with the mapped poses; report says what
  // was done.
  std::vector<io::DatasetView> test_views_in_model_frame(nlohmann::json* report) const;
  // Registers each view against the model from its pose (the pose only, photometric, full
  // resolution) and keeps the result where the fit improved and did not run away; adds how many
  // moved and by how much to report.
  Status register_test_views(std::vector<io::DatasetView>* views, nlohmann::json* report) const;
  // The training views' poses in the dataset (training_views()[i] gets poses[i]).
  void set_train_poses(const std::vector<Pose>& poses);
  // Stage 0: global initialisation by structure from motion (options.sfm_pose_init).
  Status init_by_sfm(const std::string& work_dir, const TrainProgressFn& say);
  // Stage 1: align the training poses to the SfM points (photometric, no model needed).
  Status align_to_points(const TrainProgressFn& say);
  // Stage 2: every training view's agreement with the SfM points at its pose (no model needed);
  // fills `suspect` and `view_check` (pose::suspect_views). Views whose pose the points contradict
  // are held back from training: with pose optimisation until a registration against the model
  // places them (then they are repaired), without it for the whole run.
  Status check_views(const TrainProgressFn& say);
  // The SfM points' verdict on training view v moved from its given pose to another
  // (TrainOptions::judge_new_pose).
  model::TrainOptions::PoseEvidence points_judge(size_t v, const Camera& given, const Camera& moved) const;
};

// The message when pose_init "sfm" needs an initialiser and none was given.
Status no_sfm_pose_initializer();

inline std::vector<const io::DatasetView*> pointers_to(const std::vector<io::DatasetView>& views) {
  std::vector<const io::DatasetView*> out;
  for (const io::DatasetView& v : views) out.push_back(&v);
  return out;
}

inline std::vector<Pose> poses_of(const std::vector<Camera>& cameras) {
  std::vector<Pose> out;
  for (const Camera& c : cameras) out.push_back(c.pose);
  return out;
}

inline TrainEvent text_event(TrainEvent::Kind kind, std::string message) {
  TrainEvent e;
  e.kind = kind;
  e.message = std::move(message);
  return e;
}
}  // namespace gs::jobs
