// SPDX-License-Identifier: MIT
// Example: track a video against a trained hbgs model and print the pose of every frame, as a
// device would: the model, a thread pool and a gs::pose::Tracker are set up once (planned for the
// frame size), the dataset's training views become the relocalisation candidates, then each frame
// of the video is tracked with a call that allocates nothing. Frames come from gs_capture's
// sources (a video file when hbgs was built with FFmpeg, or a folder of PNG/JPEG frames); they must
// be the size of the dataset's camera or a uniform scale of it (the intrinsics are scaled to them).
// `hbgs track` does the same with files, realtime dropping and cameras (gs/jobs/track.h).
// Built only against the installed hbgs (find_package(hbgs) -> hbgs::hbgs, or pkg-config hbgs).
//   track_video MODEL.hbgs|MODEL.hbgc DATASET VIDEO|FOLDER [MAX_FRAMES]
// Prints one line per frame: its number, verdict and (when placed) the TUM line
// "time tx ty tz qx qy qz qw" (camera centre and camera-to-world rotation in the dataset's frame).
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "gs/capture/convert.h"       // gs::capture::frame_to_rgb
#include "gs/capture/ingest.h"        // gs::capture::open_input (video file or image folder)
#include "gs/io/colmap.h"             // gs::io::load_dataset
#include "gs/io/tum.h"                // gs::io::tum_line
#include "gs/model/hybrid_model.h"    // gs::model::load_model
#include "gs/model/tracker.h"         // gs::pose::Tracker
#include "gs/platform/thread_pool.h"  // gs::platform::ThreadPool

namespace {

int failed(const char* what, const gs::Status& st) {
  std::fprintf(stderr, "track_video: %s: %s\n", what, st.to_string().c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s MODEL.hbgs|MODEL.hbgc DATASET VIDEO|FOLDER [MAX_FRAMES]\n", argv[0]);
    return 2;
  }
  const long max_frames = argc > 4 ? std::atol(argv[4]) : 0;

  // The model, and the dataset's cameras in the model's scene frame (only the test views' images
  // are decoded: the training views give their poses).
  gs::Expected<gs::model::HybridModel> model = gs::model::load_model(argv[1]);
  if (!model.ok()) return failed("model", model.status());
  gs::io::DatasetOptions dataset_options;
  dataset_options.frame = model->frame;
  dataset_options.images = gs::io::DatasetOptions::Images::kTest;
  gs::Expected<gs::io::Dataset> dataset = gs::io::load_dataset(argv[2], dataset_options);
  if (!dataset.ok()) return failed("dataset", dataset.status());
  std::vector<gs::Pose> candidates;
  for (const gs::io::DatasetView& v : dataset->views)
    if (!v.is_test) candidates.push_back(v.camera.pose);
  if (dataset->views.empty()) return failed("dataset", gs::invalid_argument("no views"));
  gs::PinholeIntrinsics K = dataset->views[0].camera.intr;

  // The frames: RGB at their own size.
  gs::Expected<std::unique_ptr<gs::capture::FrameSource>> source = gs::capture::open_input(argv[3]);
  if (!source.ok()) return failed("source", source.status());
  gs::capture::FrameSource& frames = **source;
  gs::capture::FrameFormat want, got;
  want.format = gs::capture::PixelFormat::kRGB24;
  if (gs::Status st = frames.configure(want, &got); !st.ok()) return failed("source", st);
  if (gs::Status st = frames.start(); !st.ok()) return failed("source", st);
  // The dataset's camera scaled to the frames (a uniform scale of its images is assumed here; `hbgs
  // track` checks it).
  const float sx = float(got.width) / float(K.width), sy = float(got.height) / float(K.height);
  K.fx *= sx, K.cx *= sx, K.fy *= sy, K.cy *= sy;
  K.width = got.width, K.height = got.height;

  // Set-up: the tracker plans every buffer for the model and the frame size; the candidates are
  // rendered and described once.
  gs::platform::ThreadPool pool(0);
  gs::pose::TrackOptions options;  // float renders, frames aligned at half their size
  gs::Expected<std::unique_ptr<gs::pose::Tracker>> tracker = gs::pose::Tracker::create(*model, K, options, &pool);
  if (!tracker.ok()) return failed("tracker", tracker.status());
  if (gs::Status st = (*tracker)->set_candidates(candidates); !st.ok()) return failed("candidates", st);
  (*tracker)->reset();  // the first frame is relocalised from the candidates
  std::printf("tracker planned for %dx%d: %.1f MB, %zu candidates\n", K.width, K.height,
              double((*tracker)->planned_bytes()) / 1e6, candidates.size());

  // Run: one allocation-free call per frame.
  std::vector<uint8_t> rgb(size_t(K.width) * size_t(K.height) * 3);
  long n = 0, placed = 0;
  double t0 = -1;
  for (; max_frames <= 0 || n < max_frames; ++n) {
    gs::capture::FrameView frame;
    gs::Expected<gs::capture::AcquireResult> r = frames.acquire(5000, &frame);
    if (!r.ok()) return failed("source", r.status());
    if (*r != gs::capture::AcquireResult::kFrame) break;  // the end of the file
    gs::Status st = gs::capture::frame_to_rgb(frame, rgb.data(), 3 * K.width);
    const double time = double(frame.timestamp_ns) * 1e-9;
    if (t0 < 0) t0 = time;
    if (gs::Status released = frames.release(frame); st.ok()) st = released;
    if (!st.ok()) return failed("frame", st);
    gs::pose::TrackResult result;
    if (gs::Status t = (*tracker)->track(rgb.data(), time - t0, &result); !t.ok()) return failed("track", t);
    const bool has_pose = result.verdict != gs::pose::TrackVerdict::kLost;
    placed += has_pose ? 1 : 0;
    // tum_line: "time tx ty tz qx qy qz qw" in the user's frame (the model's scene frame undone).
    const std::string pose = has_pose ? ", TUM " + gs::io::tum_line({time - t0, result.pose}, model->frame) : "";
    std::printf("frame %ld: %s%s, RMSE %.4f, %.1f ms\n", n, gs::pose::track_verdict_name(result.verdict), pose.c_str(),
                result.rmse, result.ms.total);
  }
  (void)frames.stop();
  std::printf("%ld of %ld frames placed\n", placed, n);
  return 0;
}
