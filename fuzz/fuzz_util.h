// SPDX-License-Identifier: MIT
// Shared by the libFuzzer harnesses: inputs as files for readers that take a path, and the checksum
// fix-up that lets the fuzzer past a file's FNV-1a trailer into the parser behind it.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "gs/hash.h"

namespace gs::fuzz {

// A per-process scratch file on tmpfs (each libFuzzer worker is its own process).
inline std::string scratch_path(const char* ext) {
  return "/dev/shm/hbgs_fuzz_" + std::to_string(long(::getpid())) + ext;
}

inline bool write_scratch(const std::string& path, const uint8_t* data, size_t size) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  const bool ok = std::fwrite(data, 1, size, f) == size;
  return std::fclose(f) == 0 && ok;
}

// The bytes with their last 8 replaced by the FNV-1a of the rest (little-endian), as hbgs's model and
// checkpoint writers end their files; the first input byte chooses whether to fix it (odd: fix), so
// the checksum check itself is fuzzed too.
inline std::vector<uint8_t> with_checksum(const uint8_t* data, size_t size) {
  if (size == 0) return {};
  std::vector<uint8_t> b(data + 1, data + size);
  if ((data[0] & 1) && b.size() >= 8) {
    const uint64_t h = fnv1a64(b.data(), b.size() - 8);
    for (int i = 0; i < 8; ++i) b[b.size() - 8 + size_t(i)] = uint8_t(h >> (8 * i));
  }
  return b;
}

}  // namespace gs::fuzz
