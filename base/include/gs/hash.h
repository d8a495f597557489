// SPDX-License-Identifier: MIT
// Non-cryptographic hashes: FNV-1a 64 of a byte range (the checksum of model, checkpoint and
// run-manifest files: it detects truncation and corruption, not tampering) and the hash-combine
// step that folds one value into a running hash (decision signatures, procedural noise).
#pragma once

#include <cstddef>
#include <cstdint>

namespace gs {

inline uint64_t fnv1a64(const void* data, size_t n, uint64_t h = 1469598103934665603ull) {
  const uint8_t* p = static_cast<const uint8_t*>(data);
  for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

// Folds v into the running hash h (the golden-ratio combine step of boost::hash_combine, widened
// to 64 bits). Cheap and order-sensitive; callers that need good bit mixing follow it with a
// finaliser (gs::mix64) or a multiply.
inline uint64_t hash_combine(uint64_t h, uint64_t v) { return h ^ (v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2)); }

}  // namespace gs
