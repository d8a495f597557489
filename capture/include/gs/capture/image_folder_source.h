// SPDX-License-Identifier: MIT
// ImageFolderSource: a folder of still images (.png, .jpg, .jpeg, any letter case) played back as a
// video through the FrameSource interface, so a photo set and a recorded clip go through the same
// ingestion path. Files are taken in byte-wise name order (zero-padded names such as frame_0001.png
// come out in sequence) and delivered as RGB24 at the first image's size; timestamps are synthetic,
// index * 1e9 / fps. Other files in the folder (text, sidecars, subfolders) are ignored.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/capture/frame_source.h"
#include "gs/io/image.h"

namespace gs::capture {

class ImageFolderSource : public FrameSource {
 public:
  // fps only sets the timestamps; <= 0 means the default of 30.
  explicit ImageFolderSource(std::string folder, double fps = 30.0);

  const char* name() const override { return name_.c_str(); }  // "images:<folder>"
  // Lists the folder and reads the first image for the size. Errors: the folder is missing, holds
  // no image, or its first image cannot be read. requested.format is ignored (always RGB24);
  // width/height must be 0 or the images' size (no resizing); requested.fps > 0 replaces the fps.
  Status configure(const FrameFormat& requested, FrameFormat* actual) override;
  Status start() override;
  // Decodes the next image (decoding allocates: stb_image). An unreadable image or one whose size
  // differs from the first is an error naming the file. timeout_ms is ignored.
  Expected<AcquireResult> acquire(int32_t timeout_ms, FrameView* frame) override;
  Status release(const FrameView& frame) override;
  Status stop() override;

  size_t count() const { return files_.size(); }              // images found (after configure)
  const std::string& file_name(size_t i) const { return files_[i]; }  // name inside the folder
  std::string file_path(size_t i) const { return folder_ + "/" + files_[i]; }

 private:
  std::string folder_, name_;
  double fps_;
  std::vector<std::string> files_;
  io::Image8 image_;  // the frame currently out (or the first image, read at configure)
  int32_t width_ = 0, height_ = 0;
  size_t next_ = 0;
  bool configured_ = false, started_ = false, holding_ = false, failed_ = false;
  bool first_ready_ = false;  // image_ holds file 0, read at configure, not yet delivered
};

}  // namespace gs::capture
