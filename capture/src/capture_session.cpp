// SPDX-License-Identifier: MIT
// The live capture loop behind `hbgs capture`: acquire, convert, write, release.
#include "gs/capture/capture_session.h"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <system_error>
#include <vector>

#include "gs/capture/convert.h"
#include "gs/capture/devices.h"
#include "gs/capture/image_folder_source.h"
#include "gs/capture/ingest.h"
#include "gs/io/image.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"

namespace gs::capture {

Status capture_to_folder(FrameSource& src, const std::string& folder, const CaptureOptions& o,
                         const ProgressFn& progress, CaptureReport* report) {
  CaptureReport rep;
  Status status = platform::make_dirs(folder);
  const double t0 = platform::now_seconds();
  double last_frame_time = t0, last_progress = t0;
  bool have_sequence = false;
  uint64_t last_sequence = 0;
  io::Image8 img;
  img.channels = 3;
  while (status.ok() && platform::now_seconds() - t0 < o.seconds && (o.max_frames <= 0 || rep.written < o.max_frames)) {
    FrameView frame;
    Expected<AcquireResult> r = src.acquire(200, &frame);
    if (!r.ok()) {
      status = r.status();
      break;
    }
    if (*r == AcquireResult::kEndOfStream) break;
    if (*r == AcquireResult::kTimeout) {
      if ((platform::now_seconds() - last_frame_time) * 1000.0 > o.timeout_ms)
        status = io_error(std::string(src.name()) + ": no frame for " + std::to_string(o.timeout_ms) +
                          " ms (camera stalled or disconnected)");
      continue;
    }
    last_frame_time = platform::now_seconds();
    if (have_sequence && frame.sequence > last_sequence + 1) rep.dropped += int(frame.sequence - last_sequence - 1);
    have_sequence = true;
    last_sequence = frame.sequence;
    const bool keep = rep.received % std::max(1, o.every_nth) == 0;
    ++rep.received;
    if (keep) {
      img.width = frame.width;
      img.height = frame.height;
      img.pixels.resize(size_t(frame.width) * size_t(frame.height) * 3);
      status = frame_to_rgb(frame, img.pixels.data(), 3 * frame.width);
      if (status.ok()) status = io::write_png(folder + "/" + frame_file_name(rep.written), img);
      if (status.ok()) ++rep.written;
      rep.width = frame.width;
      rep.height = frame.height;
    }
    const Status released = src.release(frame);
    if (status.ok()) status = released;
    if (progress && platform::now_seconds() - last_progress >= 1.0) {
      last_progress = platform::now_seconds();
      progress("  " + std::to_string(int(last_progress - t0)) + " s: " + std::to_string(rep.written) + " frames saved, " +
               std::to_string(rep.dropped) + " dropped");
    }
  }
  const Status stopped = src.stop();
  rep.seconds = platform::now_seconds() - t0;
  if (report != nullptr) *report = rep;
  if (!status.ok()) return status;
  if (!stopped.ok()) return stopped;
  if (rep.written == 0) return io_error(std::string(src.name()) + " delivered no frames");
  return Status::Ok();
}

Status record_and_ingest(const RecordOptions& o, const std::string& out_dir, const ProgressFn& progress,
                         CaptureReport* capture_report, IngestReport* ingest_report) {
  if (out_dir.empty()) return invalid_argument("no output folder given (--out)");
  if (o.device.empty() == o.camera.empty()) return invalid_argument("give exactly one of --device /dev/videoN or --camera ID");
  // Refuse a used output folder before touching the camera.
  GS_RETURN_IF_ERROR(check_output_folder(out_dir, o.ingest.force));
  Expected<std::unique_ptr<FrameSource>> src = o.device.empty() ? open_libcamera(o.camera) : open_v4l2_device(o.device);
  if (!src.ok()) return src.status();
  FrameFormat got;
  GS_RETURN_IF_ERROR((*src)->configure(o.requested, &got));
  if (progress) {
    char line[256];
    std::snprintf(line, sizeof(line), "capturing %s: %dx%d %s for %.1f s", (*src)->name(), got.width, got.height,
                  pixel_format_name(got.format), o.capture.seconds);
    progress(line);
  }
  GS_RETURN_IF_ERROR((*src)->start());

  std::string raw = out_dir;
  while (raw.size() > 1 && raw.back() == '/') raw.pop_back();
  raw += ".capture";
  std::error_code ec;
  std::filesystem::remove_all(raw, ec);
  CaptureReport cr;
  if (Status st = capture_to_folder(**src, raw, o.capture, progress, &cr); !st.ok())
    return Status(st.code(), st.message() + " (frames so far kept in " + raw + ")");
  if (progress)
    progress("captured " + std::to_string(cr.written) + " frames (" + std::to_string(cr.dropped) + " dropped) into " + raw);
  if (capture_report) *capture_report = cr;
  const Status st = ingest(
      [raw]() -> Expected<std::unique_ptr<FrameSource>> { return std::unique_ptr<FrameSource>(new ImageFolderSource(raw)); },
      out_dir, o.ingest, progress, ingest_report);
  if (!st.ok()) return Status(st.code(), st.message() + " (the recording is kept in " + raw + ")");
  if (!o.ingest.keep_work) std::filesystem::remove_all(raw, ec);
  return Status::Ok();
}

}  // namespace gs::capture
