// SPDX-License-Identifier: MIT
// FNV-1a 64-bit hash of a byte range: the checksum of model, checkpoint and run-manifest files. It
// detects truncation and corruption, not tampering (it is not cryptographic).
#pragma once

#include <cstddef>
#include <cstdint>

namespace gs {

inline uint64_t fnv1a64(const void* data, size_t n, uint64_t h = 1469598103934665603ull) {
  const uint8_t* p = static_cast<const uint8_t*>(data);
  for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

}  // namespace gs
