// SPDX-License-Identifier: MIT
// `hbgs capture`: list cameras, or record from a V4L2 device or a libcamera camera for a while and
// ingest the recording into a dataset (frames are first saved to OUT.capture/, then selected and
// given to COLMAP exactly as `hbgs ingest FOLDER` would).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

#include "capture_cli.h"
#include "common.h"
#include "gs/capture/capture_session.h"
#include "gs/capture/devices.h"
#include "gs/capture/image_folder_source.h"
#include "gs/capture/ingest.h"

namespace hbgs::cli {
namespace {

struct CaptureArgs {
  bool list = false;
  std::string device, camera;
  double seconds = 10.0;
  std::string format = "yuyv";
  std::string size;  // "WxH"
  double fps = 0.0;
  int every = 1;
  IngestCommonArgs common;
};

int run_list() {
  const gs::capture::DeviceListing l = gs::capture::list_capture_devices();
  for (const std::string& note : l.notes) std::printf("note: %s\n", note.c_str());
  if (l.devices.empty()) {
    std::printf("no cameras found (no V4L2 capture devices under /dev, no libcamera cameras)\n");
    return kExitOk;
  }
  for (const gs::capture::DeviceEntry& d : l.devices)
    std::printf("%-10s %-24s %s%s%s\n", d.backend.c_str(), d.id.c_str(), d.description.c_str(),
                d.formats.empty() ? "" : "  formats: ", d.formats.c_str());
  return kExitOk;
}

bool parse_size(const std::string& text, int* w, int* h) {
  if (text.empty()) return true;
  char x = 0;
  return std::sscanf(text.c_str(), "%d%c%d", w, &x, h) == 3 && (x == 'x' || x == 'X') && *w > 0 && *h > 0;
}

int run_capture(const CaptureArgs& a) {
  if (a.list) return run_list();
  if (a.common.out.empty()) return fail("capture", "--out is required (or use --list)");
  if (a.device.empty() == a.camera.empty()) return fail("capture", "give exactly one of --device /dev/videoN or --camera ID");
  gs::capture::IngestOptions o;
  if (int rc = ingest_options_from(a.common, "capture", &o); rc != kExitOk) return rc;
  gs::capture::FrameFormat want;
  gs::Expected<gs::capture::PixelFormat> pf = gs::capture::parse_pixel_format(a.format);
  if (!pf.ok()) return fail("capture", pf.status().message());
  want.format = *pf;
  want.fps = a.fps;
  if (!parse_size(a.size, &want.width, &want.height)) return fail("capture", "--size must look like 640x480");
  // Refuse a used output folder before touching the camera.
  if (gs::Status st = gs::capture::check_output_folder(a.common.out, a.common.force); !st.ok())
    return fail("capture", st.message());

  gs::Expected<std::unique_ptr<gs::capture::FrameSource>> src =
      a.device.empty() ? gs::capture::open_libcamera(a.camera) : gs::capture::open_v4l2_device(a.device);
  if (!src.ok()) return fail("capture", src.status().message());
  gs::capture::FrameFormat got;
  if (gs::Status st = (*src)->configure(want, &got); !st.ok()) return fail("capture", st.message());
  std::printf("capturing %s: %dx%d %s for %.1f s\n", (*src)->name(), got.width, got.height,
              gs::capture::pixel_format_name(got.format), a.seconds);
  if (gs::Status st = (*src)->start(); !st.ok()) return fail("capture", st.message());

  std::string raw = a.common.out;
  while (raw.size() > 1 && raw.back() == '/') raw.pop_back();
  raw += ".capture";
  std::error_code ec;
  std::filesystem::remove_all(raw, ec);
  gs::capture::CaptureOptions co;
  co.seconds = a.seconds;
  co.every_nth = a.every;
  gs::capture::CaptureReport cr;
  if (gs::Status st = gs::capture::capture_to_folder(**src, raw, co, print_progress, &cr); !st.ok())
    return fail("capture", st.message() + " (frames so far kept in " + raw + ")");
  std::printf("captured %d frames (%d dropped) in %.1f s into %s\n", cr.written, cr.dropped, cr.seconds, raw.c_str());

  gs::capture::IngestReport report;
  Stopwatch sw;
  const gs::Status st = gs::capture::ingest(
      [raw]() -> gs::Expected<std::unique_ptr<gs::capture::FrameSource>> {
        return std::unique_ptr<gs::capture::FrameSource>(new gs::capture::ImageFolderSource(raw));
      },
      a.common.out, o, print_progress, &report);
  if (!st.ok()) return fail("capture", st.to_string() + " (the recording is kept in " + raw + ")");
  if (!a.common.keep_work) std::filesystem::remove_all(raw, ec);
  print_ingest_summary(report, a.common.out, sw.seconds());
  return kExitOk;
}

}  // namespace

Command add_capture_command(CLI::App& parent) {
  auto args = std::make_shared<CaptureArgs>();
  CLI::App* sub = parent.add_subcommand("capture", "Record from a camera and make a dataset (or --list the cameras)");
  sub->add_flag("--list", args->list, "List the cameras this build can open, then exit");
  sub->add_option("--device", args->device, "V4L2 device, e.g. /dev/video0");
  sub->add_option("--camera", args->camera, "libcamera camera id (see --list)");
  sub->add_option("--seconds", args->seconds, "How long to record")->capture_default_str()->check(CLI::Range(0.1, 86400.0));
  sub->add_option("--format", args->format, "Pixel format to ask for: yuyv, nv12 or mjpeg")->capture_default_str();
  sub->add_option("--size", args->size, "Frame size to ask for, e.g. 1280x720 (default: the camera's)");
  sub->add_option("--fps", args->fps, "Frame rate to ask for (default: the camera's)")->check(CLI::Range(0.0, 1000.0));
  sub->add_option("--every", args->every, "Save every n-th frame")->capture_default_str()->check(CLI::Range(1, 1000));
  add_ingest_options(sub, &args->common, false);
  return {sub, [args] { return run_capture(*args); }};
}

}  // namespace hbgs::cli
