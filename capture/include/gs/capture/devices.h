// SPDX-License-Identifier: MIT
// The live cameras this build can open: V4L2 nodes (/dev/video*) and libcamera cameras, listed
// together for `hbgs capture --list`, and opened by path or id. A backend compiled out is
// reported as such, so "no cameras" and "this build cannot see cameras" are not confused.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "gs/capture/frame_source.h"
#include "gs/status.h"

namespace gs::capture {

struct DeviceEntry {
  std::string backend;      // "v4l2" or "libcamera"
  std::string id;           // what --device / --camera takes
  std::string description;  // card / model name
  std::string formats;      // e.g. "YUYV MJPG" (V4L2 only)
};

struct DeviceListing {
  std::vector<DeviceEntry> devices;
  std::vector<std::string> notes;  // backends compiled out or failing, one line each
};

DeviceListing list_capture_devices();

// /dev/videoN (V4L2) or a libcamera camera id; errors say which backends exist in this build.
Expected<std::unique_ptr<FrameSource>> open_v4l2_device(const std::string& path);
Expected<std::unique_ptr<FrameSource>> open_libcamera(const std::string& id);

}  // namespace gs::capture
