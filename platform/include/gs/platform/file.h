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

// An exclusive advisory lock (flock) on a file, held until destruction: one writer per run folder.
// The lock file holds the owner's pid for the message a second process gets; it is never removed
// (removing a lock file races with a process that opened it just before).
class FileLock {
 public:
  // Fails at once (no waiting) with an io_error naming the holder's pid when
  // another process holds the lock; `what` names the protected thing in messages ("run folder X").
  static Expected<FileLock> acquire(const std::string& lock_path, const std::string& what);
  FileLock() = default;
  FileLock(FileLock&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }
  FileLock& operator=(FileLock&& o) noexcept;
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;
  ~FileLock();
  bool held() const { return fd_ >= 0; }

 private:
  explicit FileLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

// Fault injection, for tests only (tests/jobs/test_fault_injection.cpp): from the call on, the
// k-th write_file_atomic of this process (1-based, counted over all threads) fails the way a full
// or broken disk does, and the target file keeps its old content. kShortWrite: half of the bytes
// reach the temporary file, then ENOSPC; kNoSpace: the first write() gets ENOSPC; kIoError: fsync
// gets EIO. k = 0 disarms. write_file_atomic_calls() counts calls since the last arm or reset.
enum class WriteFault { kShortWrite, kNoSpace, kIoError };
void inject_write_fault(uint64_t k, WriteFault kind);
uint64_t write_file_atomic_calls();

}  // namespace gs::platform
