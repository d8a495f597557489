// SPDX-License-Identifier: MIT
// The COLMAP pose initialiser of `hbgs train --pose-init sfm` (colmap_pose_init.h): the training
// job's SfmPoseInitializer made of gs_capture's image choice (sfm_images.h) and SfM initialisation
// (sfm_pose_init.h).
#include "colmap_pose_init.h"

#include "gs/capture/colmap_sfm.h"
#include "gs/capture/sfm_images.h"
#include "gs/capture/sfm_pose_init.h"

namespace hbgs::cli {

namespace {

using gs::Camera;
using gs::Expected;
using gs::Status;
using gs::jobs::SfmPoseInitializer;
using gs::jobs::SfmPoseInitRequest;
using gs::jobs::SfmPoseInitResult;
using gs::jobs::TrainEvent;
using gs::jobs::TrainProgressFn;
namespace capture = gs::capture;
namespace io = gs::io;

void say_text(const TrainProgressFn& say, TrainEvent::Kind kind, std::string message) {
  TrainEvent e;
  e.kind = kind;
  e.message = std::move(message);
  say(e);
}

class ColmapPoseInitializer final : public SfmPoseInitializer {
 public:
  Status check(const std::string& dataset_folder, const std::string& sfm_images, const std::string& colmap) const override {
    if (Status st = capture::check_sfm_images_choice(dataset_folder, sfm_images); !st.ok())
      return Status(st.code(), "--sfm-images: " + st.message());
    capture::ColmapOptions copt;
    copt.colmap = colmap;
    if (Status st = capture::check_colmap(copt); !st.ok()) return Status(st.code(), "--pose-init sfm: " + st.message());
    return Status::Ok();
  }

  Status run(const SfmPoseInitRequest& request, const TrainProgressFn& progress, SfmPoseInitResult* result) const override {
    const TrainProgressFn say = progress ? progress : [](const TrainEvent&) {};
    capture::SfmPoseInitOptions so;
    so.colmap.colmap = request.colmap;
    so.colmap.matcher = capture::Matcher::kExhaustive;
    so.colmap.threads = request.threads;
    Expected<capture::SfmImages> sfm_images =
        capture::choose_sfm_images(request.dataset_folder, request.sfm_images, request.views, so.colmap.max_image_size);
    if (!sfm_images.ok()) return gs::invalid_argument("--sfm-images: " + sfm_images.status().message());
    std::vector<Camera> cams = sfm_images->cameras;
    std::vector<const io::Image8*> images;
    for (size_t i = 0; i < request.views.size(); ++i)
      images.push_back(sfm_images->folder.empty() ? &request.views[i]->image : &sfm_images->images[i]);
    if (!sfm_images->note.empty()) say_text(say, TrainEvent::kNote, sfm_images->note);
    say_text(say, TrainEvent::kStage,
             "initialising " + std::to_string(cams.size()) + " training poses by structure from motion (COLMAP on " +
                 (sfm_images->folder.empty() ? std::string("the training images") : sfm_images->folder) + ", " +
                 std::to_string(cams[0].intr.width) + "x" + std::to_string(cams[0].intr.height) + ")...");
    const capture::ProgressFn lines = [&](const std::string& line) { say_text(say, TrainEvent::kDetail, "  " + line); };
    capture::SfmPoseInitReport rep;
    if (Status st = capture::init_poses_by_sfm(images, request.names, &cams, request.points_xyz, request.points, request.work_dir,
                                               so, lines, &rep);
        !st.ok())
      return Status(st.code(), "--pose-init sfm: " + st.message());
    SfmPoseInitResult r;
    for (const Camera& c : cams) r.poses.push_back(c.pose);
    r.registered = rep.registered_views;
    r.suspect = rep.suspect_views;
    r.disagreement_deg = rep.disagreement_deg;
    r.chosen_seed = rep.chosen_seed;
    r.first_run_suspect = rep.first_run_suspect;
    r.images = sfm_images->folder.empty() ? std::string("training images") : sfm_images->folder;
    r.image_width = cams[0].intr.width;
    r.image_height = cams[0].intr.height;
    r.views = rep.views;
    r.registered_views = rep.registered;
    r.colmap_points = rep.colmap_points;
    r.icp_pairs = rep.icp_pairs;
    r.icp_iterations = rep.icp_iterations;
    r.seconds = rep.seconds;
    r.centre_fit_rms = rep.centre_fit_rms;
    r.icp_median_before = rep.icp_median_before;
    r.icp_median_after = rep.icp_median_after;
    *result = std::move(r);
    return Status::Ok();
  }
};

}  // namespace

const SfmPoseInitializer& colmap_pose_initializer() {
  static const ColmapPoseInitializer initializer;
  return initializer;
}

}  // namespace hbgs::cli
