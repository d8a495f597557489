// SPDX-License-Identifier: MIT
// `hbgs track`'s frames: gs_capture's frame sources (video files, image folders, V4L2 devices,
// libcamera cameras) behind the tracking job's gs::jobs::FrameStream. It lives in the program, not
// in gs_jobs, so that the jobs library and hbgs-device link no capture code (hbgs-device is built
// without this file and reads image folders through the job's own stream).
#pragma once

#include <memory>
#include <string>

#include "gs/jobs/track.h"

namespace hbgs::cli {

// SOURCE: "libcamera:ID" (an id or index as `hbgs capture --list` shows), a V4L2 device
// ("/dev/videoN", any character device, or "v4l2:PATH"), else a video file or an image folder
// (gs::capture::open_input). A camera is asked for width x height (0: its default) in YUYV, else
// MJPEG, else NV12; file sources deliver their own size as RGB.
gs::Expected<std::unique_ptr<gs::jobs::FrameStream>> open_capture_stream(const std::string& source, int width, int height);

}  // namespace hbgs::cli
