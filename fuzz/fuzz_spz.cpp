// SPDX-License-Identifier: MIT
// libFuzzer harness: the Niantic .spz reader (gzip stream, header, counts against the inflated
// size, the gzip-bomb cap, fixed-point and smallest-three decoding).
#include <cstdint>

#include "gs/io/splat_formats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)gs::io::parse_spz(data, size, "fuzz.spz");
  return 0;
}
