// SPDX-License-Identifier: MIT
// Helpers for the gs_io tests: a self-deleting temp folder, raw file and image writes, the
// shared-data path and substring checks on error messages.
#pragma once

#include <doctest/doctest.h>
#include <stdlib.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gs/io/image.h"
#include "gs/status.h"
#include "support/temp_dir.h"

namespace gs::io::test {

using gs::test::TempDir;

inline void write_bytes(const std::string& path, const void* data, size_t size) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream f(path, std::ios::binary);
  f.write(static_cast<const char*>(data), std::streamsize(size));
  REQUIRE(f.good());
}
inline void write_bytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  write_bytes(path, bytes.data(), bytes.size());
}
inline void write_text(const std::string& path, const std::string& text) { write_bytes(path, text.data(), text.size()); }

// An image file written with hbgs's own writers, its folder made first.
inline void put_png(const std::string& path, const Image8& img) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  REQUIRE(write_png(path, img).ok());
}
inline void put_jpeg(const std::string& path, const Image8& img) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  REQUIRE(write_jpeg(path, img).ok());
}

inline std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

// Real scenes live next to the repository (../shared/data); tests skip with a message without them.
inline std::string shared_data(const std::string& rel) { return std::string(GS_SOURCE_DIR) + "/../shared/data/" + rel; }
inline bool have_shared_data(const std::string& rel) {
  if (std::filesystem::exists(shared_data(rel))) return true;
  MESSAGE("skipped: " << shared_data(rel) << " is not available");
  return false;
}

inline bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

// Checks that `status` failed and that its message mentions every string in `needles`.
inline void check_error(const Status& status, std::initializer_list<std::string> needles) {
  REQUIRE_FALSE(status.ok());
  for (const std::string& n : needles) CHECK_MESSAGE(contains(status.message(), n), "'" << n << "' not in: " << status.message());
}

}  // namespace gs::io::test
