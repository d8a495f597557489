// SPDX-License-Identifier: MIT
// Little-endian byte access that does not depend on the host's byte order: the readers and writers
// of every binary file hbgs handles (COLMAP, PLY, splat formats, model and checkpoint files).
#pragma once

#include <cstdint>
#include <cstring>
#include <vector>

namespace gs::bytes {

// The `bytes`-byte little-endian unsigned value at p (bytes in 1..8).
inline uint64_t load_le(const uint8_t* p, int bytes) {
  uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}
inline uint32_t load_u32(const uint8_t* p) { return uint32_t(load_le(p, 4)); }
inline uint64_t load_u64(const uint8_t* p) { return load_le(p, 8); }
inline float load_f32(const uint8_t* p) {
  uint32_t bits = load_u32(p);
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}
inline double load_f64(const uint8_t* p) {
  uint64_t bits = load_u64(p);
  double d;
  std::memcpy(&d, &bits, 8);
  return d;
}

// Appends the low `bytes` bytes of v, least significant first.
inline void append_le(std::vector<uint8_t>& out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(uint8_t(v >> (8 * i)));
}
inline void append_u32(std::vector<uint8_t>& out, uint32_t v) { append_le(out, v, 4); }
inline void append_u64(std::vector<uint8_t>& out, uint64_t v) { append_le(out, v, 8); }
inline void append_f32(std::vector<uint8_t>& out, float f) {
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  append_le(out, bits, 4);
}
inline void append_f64(std::vector<uint8_t>& out, double d) {
  uint64_t bits;
  std::memcpy(&bits, &d, 8);
  append_le(out, bits, 8);
}

}  // namespace gs::bytes
