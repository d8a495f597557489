// SPDX-License-Identifier: MIT
// `hbgs capture`: list cameras, or record from a V4L2 device or a libcamera camera for a while and
// ingest the recording into a dataset (frames are first saved to OUT.capture/, then selected and
// given to COLMAP exactly as `hbgs ingest FOLDER` would).
#include <cstdio>
#include <memory>
#include <string>

#include "capture_cli.h"
#include "common.h"
#include "gs/capture/capture_session.h"
#include "gs/capture/devices.h"
#include "gs/capture/ingest.h"

namespace hbgs::cli {
namespace {

struct CaptureArgs {
  bool list = false;
  std::string out;
  gs::capture::RecordOptions options;
  std::string format = "yuyv";
  std::string size;  // "WxH"
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

int run_capture(CaptureArgs& a) {
  if (a.list) return run_list();
  if (a.out.empty()) return fail("capture", "--out is required (or use --list)");
  gs::capture::FrameFormat& want = a.options.requested;
  gs::Expected<gs::capture::PixelFormat> pf = gs::capture::parse_pixel_format(a.format);
  if (!pf.ok()) return fail("capture", pf.status().message());
  want.format = *pf;
  if (!parse_size(a.size, &want.width, &want.height)) return fail("capture", "--size must look like 640x480");
  gs::capture::CaptureReport cr;
  gs::capture::IngestReport report;
  Stopwatch sw;
  if (gs::Status st = gs::capture::record_and_ingest(a.options, a.out, print_progress, &cr, &report); !st.ok())
    return fail("capture", st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
  print_ingest_summary(report, a.out, sw.seconds());
  return kExitOk;
}

}  // namespace

Command add_capture_command(CLI::App& parent) {
  auto args = std::make_shared<CaptureArgs>();
  CLI::App* sub = parent.add_subcommand("capture", "Record from a camera and make a dataset (or --list the cameras)");
  sub->add_flag("--list", args->list, "List the cameras this build can open, then exit");
  gs::capture::RecordOptions* o = &args->options;
  sub->add_option("--device", o->device, "V4L2 device, e.g. /dev/video0");
  sub->add_option("--camera", o->camera, "libcamera camera id (see --list)");
  sub->add_option("--seconds", o->capture.seconds, "How long to record")->capture_default_str()->check(CLI::Range(0.1, 86400.0));
  sub->add_option("--format", args->format, "Pixel format to ask for: yuyv, nv12 or mjpeg")->capture_default_str();
  sub->add_option("--size", args->size, "Frame size to ask for, e.g. 1280x720 (default: the camera's)");
  sub->add_option("--fps", o->requested.fps, "Frame rate to ask for (default: the camera's)")->check(CLI::Range(0.0, 1000.0));
  sub->add_option("--every", o->capture.every_nth, "Save every n-th frame")->capture_default_str()->check(CLI::Range(1, 1000));
  add_ingest_options(sub, &args->out, &o->ingest, false);
  return {sub, [args] { return run_capture(*args); }};
}

}  // namespace hbgs::cli
