// SPDX-License-Identifier: MIT
// libFuzzer harness: PNG/JPEG decoding (stb_image behind hbgs's size and channel checks), to RGB and
// to grey.
#include <cstdint>

#include "gs/io/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)gs::io::decode_image(data, size, 3, "fuzz image");
  if (size > 0 && (data[0] & 1)) (void)gs::io::decode_image(data, size, 1, "fuzz image");
  return 0;
}
