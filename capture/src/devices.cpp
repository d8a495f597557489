// SPDX-License-Identifier: MIT
// One listing of the cameras every compiled-in backend sees, and opening a camera by path or id.
#include "gs/capture/devices.h"

#if defined(GS_HAVE_V4L2)
#include "gs/capture/v4l2_device.h"
#include "gs/capture/v4l2_source.h"
#endif
#if defined(GS_HAVE_LIBCAMERA)
#include "gs/capture/libcamera_source.h"
#endif

namespace gs::capture {

DeviceListing list_capture_devices() {
  DeviceListing l;
#if defined(GS_HAVE_V4L2)
  Expected<std::vector<V4l2DeviceInfo>> v4l2 = list_v4l2_devices(system_v4l2_device());
  if (!v4l2.ok()) {
    l.notes.push_back("V4L2: " + v4l2.status().message());
  } else {
    for (const V4l2DeviceInfo& d : *v4l2) {
      DeviceEntry e{"v4l2", d.path, d.card, ""};
      if (!d.error.empty()) e.description = "(" + d.error + ")";
      for (uint32_t f : d.formats) e.formats += (e.formats.empty() ? "" : " ") + fourcc_text(f);
      l.devices.push_back(e);
    }
  }
#else
  l.notes.push_back("V4L2: not in this build (linux/videodev2.h was missing)");
#endif
#if defined(GS_HAVE_LIBCAMERA)
  Expected<std::vector<CameraInfo>> cams = list_libcamera_cameras();
  if (!cams.ok()) {
    l.notes.push_back("libcamera: " + cams.status().message());
  } else {
    for (const CameraInfo& c : *cams) l.devices.push_back({"libcamera", c.id, c.model, ""});
  }
#else
  l.notes.push_back("libcamera: not in this build (libcamera-dev was missing)");
#endif
  return l;
}

Expected<std::unique_ptr<FrameSource>> open_v4l2_device(const std::string& path) {
#if defined(GS_HAVE_V4L2)
  return std::unique_ptr<FrameSource>(new V4l2Source(path, system_v4l2_device()));
#else
  return unsupported("cannot open " + path + ": hbgs was built without V4L2 support");
#endif
}

Expected<std::unique_ptr<FrameSource>> open_libcamera(const std::string& id) {
#if defined(GS_HAVE_LIBCAMERA)
  return std::unique_ptr<FrameSource>(new LibcameraSource(id));
#else
  return unsupported("cannot open camera '" + id + "': hbgs was built without libcamera (install libcamera-dev and rebuild)");
#endif
}

}  // namespace gs::capture
