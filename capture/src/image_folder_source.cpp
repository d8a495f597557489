// SPDX-License-Identifier: MIT
// ImageFolderSource: lists the folder once at configure (so the frame count is known up front and
// files added later do not change a running ingest), decodes one image per acquire with gs::io's
// stb-based reader and hands out a view of that image's pixels until release.
#include "gs/capture/image_folder_source.h"

#include <utility>

#include "gs/platform/file.h"

namespace gs::capture {

ImageFolderSource::ImageFolderSource(std::string folder, double fps)
    : folder_(std::move(folder)), name_("images:" + folder_), fps_(fps > 0 ? fps : 30.0) {}

Status ImageFolderSource::configure(const FrameFormat& requested, FrameFormat* actual) {
  configured_ = started_ = holding_ = failed_ = first_ready_ = false;
  files_.clear();
  next_ = 0;
  const std::string where = "image folder " + folder_;
  if (!platform::is_directory(folder_))
    return io_error(where + (platform::file_exists(folder_) ? ": not a directory" : ": no such folder"));

  Expected<std::vector<std::string>> listed = io::list_image_files(folder_);
  if (!listed.ok()) return Status(listed.status().code(), where + ": " + listed.status().message());
  files_ = std::move(listed).value();
  if (files_.empty()) return invalid_argument(where + ": no .png, .jpg or .jpeg images in it");

  auto first = io::read_image(file_path(0), 3);
  if (!first.ok()) return Status(first.status().code(), where + ": " + first.status().message());
  image_ = std::move(first.value());
  width_ = image_.width;
  height_ = image_.height;
  if ((requested.width != 0 || requested.height != 0) && (requested.width != width_ || requested.height != height_))
    return invalid_argument(where + ": images are " + std::to_string(width_) + "x" + std::to_string(height_) +
                            ", cannot deliver " + std::to_string(requested.width) + "x" +
                            std::to_string(requested.height) + " (no resizing; ask for 0x0)");
  if (requested.fps > 0) fps_ = requested.fps;
  first_ready_ = true;
  configured_ = true;
  if (actual) {
    actual->width = width_;
    actual->height = height_;
    actual->format = PixelFormat::kRGB24;
    actual->fps = fps_;
  }
  return Status::Ok();
}

Status ImageFolderSource::start() {
  if (!configured_) return invalid_argument(name_ + ": start before a successful configure");
  started_ = true;
  return Status::Ok();
}

Expected<AcquireResult> ImageFolderSource::acquire(int32_t /*timeout_ms*/, FrameView* frame) {
  if (!started_) return invalid_argument(name_ + ": acquire before start");
  if (failed_) return invalid_argument(name_ + ": acquire after an error (only stop is allowed)");
  if (holding_) return invalid_argument(name_ + ": acquire while a frame is still held (release it first)");
  if (next_ >= files_.size()) return AcquireResult::kEndOfStream;

  const std::string path = file_path(next_);
  if (!first_ready_ || next_ != 0) {
    auto img = io::read_image(path, 3);
    if (!img.ok()) {
      failed_ = true;
      // read_image's message already names the file; prefix the folder source for context.
      return Status(img.status().code(), name_ + ": image " + std::to_string(next_) + ": " + img.status().message());
    }
    if (img->width != width_ || img->height != height_) {
      failed_ = true;
      return invalid_argument(name_ + ": " + path + " is " + std::to_string(img->width) + "x" +
                              std::to_string(img->height) + " but the first image (" + files_[0] + ") is " +
                              std::to_string(width_) + "x" + std::to_string(height_));
    }
    image_ = std::move(img.value());
  }
  first_ready_ = false;

  FrameView v;
  v.width = width_;
  v.height = height_;
  v.format = PixelFormat::kRGB24;
  v.num_planes = 1;
  v.planes[0].data = image_.pixels.data();
  v.planes[0].size = image_.pixels.size();
  v.planes[0].stride = width_ * 3;
  v.timestamp_ns = int64_t(double(next_) * (1e9 / fps_) + 0.5);
  v.sequence = next_;
  v.buffer_index = 0;
  *frame = v;
  ++next_;
  holding_ = true;
  return AcquireResult::kFrame;
}

Status ImageFolderSource::release(const FrameView& frame) {
  if (!holding_) return invalid_argument(name_ + ": release without an acquired frame");
  if (frame.planes[0].data != image_.pixels.data())
    return invalid_argument(name_ + ": release of a frame this source did not hand out");
  holding_ = false;
  return Status::Ok();
}

Status ImageFolderSource::stop() {
  started_ = false;
  holding_ = false;
  return Status::Ok();
}

}  // namespace gs::capture
