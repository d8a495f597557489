// SPDX-License-Identifier: MIT
// libFuzzer harness: the .hbgc compact model reader. The first byte chooses whether the FNV-1a trailer is
// made to match (fuzz_util.h), so both the checksum check and the parser behind it are reached.
#include <cstdint>
#include <vector>

#include "fuzz_util.h"
#include "gs/model/compact_model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<uint8_t> b = gs::fuzz::with_checksum(data, size);
  (void)gs::model::deserialize_compact(b.data(), b.size(), "fuzz.hbgc");
  return 0;
}
