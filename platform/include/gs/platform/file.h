// SPDX-License-Identifier: MIT
// File access for hbgs: whole-file reads and atomic writes (write to a temporary file in the same
// folder, fsync, rename), so a crash never leaves a half-written output behind.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/status.h"

namespace gs::platform {

// Refuses files larger than max_bytes (default 4 GiB) with a clear error before reading.
Expected<std::vector<uint8_t>> read_file(const std::string& path, uint64_t max_bytes = (uint64_t(1) << 32));
Expected<std::string> read_text_file(const std::string& path, uint64_t max_bytes = (uint64_t(1) << 32));
// Writes "<path>.tmp.<pid>", fsyncs it and renames it over path. On failure the temp file is
// removed, path keeps its old content, and the error names path and the OS's reason.
Status write_file_atomic(const std::string& path, const void* data, size_t size);
Status write_file_atomic(const std::string& path, const std::string& text);
Status make_dirs(const std::string& path);  // mkdir -p; an existing directory is success
bool file_exists(const std::string& path);   // any kind of entry (file, directory, device), after symlinks
bool is_directory(const std::string& path);
// Absolute path of the running program (/proc/self/exe), "" when the OS does not say.
std::string executable_path();

}  // namespace gs::platform
