// SPDX-License-Identifier: MIT
// libFuzzer harness: the PlayCanvas compressed.ply reader and the format dispatcher in front of it
// (PLY header, element layout, chunk bounds, packed fields; the first byte picks the entry point).
#include <cstdint>

#include "gs/io/splat_formats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  if (data[0] & 1)
    (void)gs::io::parse_gaussians(data + 1, size - 1, "fuzz.ply");
  else
    (void)gs::io::parse_compressed_ply(data + 1, size - 1, "fuzz.compressed.ply");
  return 0;
}
