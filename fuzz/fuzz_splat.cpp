// SPDX-License-Identifier: MIT
// libFuzzer harness: the antimatter15 .splat reader (record count, floats, 8-bit fields).
#include <cstdint>

#include "gs/io/splat_formats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)gs::io::parse_antimatter_splat(data, size, "fuzz.splat");
  return 0;
}
