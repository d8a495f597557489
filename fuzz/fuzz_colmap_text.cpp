// SPDX-License-Identifier: MIT
// libFuzzer harness: the COLMAP text parsers. The first byte picks cameras.txt, images.txt or
// points3D.txt (value % 3); the rest is the file's text.
#include <cstdint>
#include <string>
#include <vector>

#include "gs/io/colmap.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string text(reinterpret_cast<const char*>(data + 1), size - 1);
  switch (data[0] % 3) {
    case 0: {
      std::vector<gs::io::ColmapCamera> out;
      (void)gs::io::parse_cameras_text(text, "cameras.txt", &out);
      break;
    }
    case 1: {
      std::vector<gs::io::ColmapImage> out;
      (void)gs::io::parse_images_text(text, "images.txt", &out);
      break;
    }
    default: {
      std::vector<gs::io::ColmapPoint3D> out;
      (void)gs::io::parse_points3d_text(text, "points3D.txt", &out);
    }
  }
  return 0;
}
