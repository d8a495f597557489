// SPDX-License-Identifier: MIT
// libFuzzer harness: the 3DGS PLY reader (header, counts, properties, vertex data).
#include <cstdint>

#include "gs/io/ply.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)gs::io::parse_splat_ply(data, size, "fuzz.ply");
  return 0;
}
