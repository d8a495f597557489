// SPDX-License-Identifier: MIT
// Ingestion: frames from any FrameSource (video file, image folder, a finished capture) to a
// dataset `hbgs train` reads. Two passes over the source: the first measures every frame
// (sharpness, motion) and picks the frames to keep; the second writes only those as PNG. COLMAP
// then recovers the cameras. All work happens in "<out>.partial"; the output folder appears (or is
// replaced, with force) by a rename only when everything succeeded, so a failed run never leaves a
// half-written dataset behind. On failure the partial folder stays, with COLMAP's log, for
// inspection; the next run starts it afresh.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "gs/capture/colmap_sfm.h"
#include "gs/capture/frame_select.h"
#include "gs/capture/frame_source.h"
#include "gs/status.h"

namespace gs::capture {

using SourceFactory = std::function<Expected<std::unique_ptr<FrameSource>>()>;

struct IngestOptions {
  SelectOptions select;
  ColmapOptions colmap;
  int max_width = 1600;   // kept frames wider than this are downscaled (area filter); 0 = keep size
  bool force = false;     // replace an existing dataset in the output folder
  bool keep_work = false; // keep <out>/work (selected raw frames, COLMAP database, raw models)
};

struct IngestReport {
  std::string source;
  int width = 0, height = 0;        // frames as decoded
  int out_width = 0, out_height = 0;
  SelectReport select;
  std::vector<int64_t> kept_frames; // source frame numbers of the frames given to COLMAP
  ColmapReport colmap;
  double seconds_analyse = 0, seconds_write = 0, seconds_total = 0;
};

// Refuses an output folder that exists as a file, or holds anything (a dataset or other files)
// unless force is set. The message says what is there and how to proceed.
Status check_output_folder(const std::string& out_dir, bool force);

// Opens a video file (needs libav at build time) or a folder of PNG/JPEG images.
Expected<std::unique_ptr<FrameSource>> open_input(const std::string& path);

// The file name a kept frame gets: "frame_000123.png" for source frame 123.
std::string frame_file_name(int64_t frame_index);

// Runs the whole pipeline. progress receives human-readable lines (may be empty).
Status ingest(const SourceFactory& make_source, const std::string& out_dir, const IngestOptions& options,
              const ProgressFn& progress, IngestReport* report);

}  // namespace gs::capture
