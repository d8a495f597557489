// SPDX-License-Identifier: MIT
// libFuzzer harness: the COLMAP binary parsers. The first byte picks cameras.bin, images.bin or
// points3D.bin (value % 3); the rest is the file's bytes.
#include <cstdint>
#include <vector>

#include "gs/io/colmap.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t* body = data + 1;
  const size_t n = size - 1;
  switch (data[0] % 3) {
    case 0: {
      std::vector<gs::io::ColmapCamera> out;
      (void)gs::io::parse_cameras_binary(body, n, "cameras.bin", &out);
      break;
    }
    case 1: {
      std::vector<gs::io::ColmapImage> out;
      (void)gs::io::parse_images_binary(body, n, "images.bin", &out);
      break;
    }
    default: {
      std::vector<gs::io::ColmapPoint3D> out;
      (void)gs::io::parse_points3d_binary(body, n, "points3D.bin", &out);
    }
  }
  return 0;
}
