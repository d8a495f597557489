// SPDX-License-Identifier: MIT
// Live capture to a folder: pulls frames from a configured, started FrameSource for a fixed time
// and writes each as an RGB PNG (frame_000000.png, ...), which `ingest` then reads as an image
// folder. Frames the writer cannot keep up with are dropped by the device's ring, not queued
// without bound; the drops are counted from gaps in the sequence numbers.
#pragma once

#include <cstdint>
#include <string>

#include "gs/capture/colmap_sfm.h"
#include "gs/capture/frame_source.h"
#include "gs/capture/ingest.h"
#include "gs/status.h"

namespace gs::capture {

struct CaptureOptions {
  double seconds = 10.0;    // stop after this long (source clock is not trusted: wall clock)
  int max_frames = 0;       // > 0: stop after this many frames were written
  int every_nth = 1;        // write every n-th frame (thins a fast camera)
  int32_t timeout_ms = 2000; // no frame for this long is an error (a camera that stalled)
};

struct CaptureReport {
  int written = 0;   // frames saved
  int received = 0;  // frames acquired
  int dropped = 0;   // gaps in the source's sequence numbers
  int width = 0, height = 0;
  double seconds = 0;
};

// source must be configured and started; it is stopped on return.
Status capture_to_folder(FrameSource& source, const std::string& folder, const CaptureOptions& options,
                         const ProgressFn& progress, CaptureReport* report);

// The whole `hbgs capture` job: opens the camera (a V4L2 device path or a libcamera id, exactly
// one), asks it for `requested` (zero fields: the camera's choice), records into <out_dir>.capture/
// for options.seconds, then ingests that folder into out_dir as ingest() does. The recording is
// kept when ingestion fails (and with ingest.keep_work); the output folder is checked before the
// camera is touched.
struct RecordOptions {
  std::string device;  // V4L2 device, e.g. /dev/video0
  std::string camera;  // libcamera camera id
  FrameFormat requested;
  CaptureOptions capture;
  IngestOptions ingest;
};
Status record_and_ingest(const RecordOptions& options, const std::string& out_dir, const ProgressFn& progress,
                         CaptureReport* capture_report, IngestReport* ingest_report);

}  // namespace gs::capture
