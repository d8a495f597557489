// SPDX-License-Identifier: MIT
// libFuzzer harness: the point-cloud PLY reader (ascii and binary headers, counts, vertex values).
#include <cstdint>

#include "gs/io/transforms.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)gs::io::parse_point_ply(data, size, "points.ply");
  return 0;
}
