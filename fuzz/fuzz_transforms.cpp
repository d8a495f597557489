// SPDX-License-Identifier: MIT
// libFuzzer harness: the transforms.json parser (JSON syntax, frames, intrinsics, pose checks).
#include <cstdint>
#include <string>

#include "gs/io/transforms.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  gs::io::TransformsFile file;
  (void)gs::io::parse_transforms_json(text, "transforms.json", &file);
  return 0;
}
