// SPDX-License-Identifier: MIT
// POSIX file access: bounded whole-file reads and crash-safe writes (temp file in the same folder,
// fsync, rename). Every error names the path and the OS's reason, because these messages are what a
// user sees when a dataset or output folder is wrong.
#include "gs/platform/file.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <algorithm>
#include <cstdint>
#include <string>
#include <system_error>
#include <vector>

#include "errno_text.h"

namespace gs::platform {
namespace {

using detail::errno_text;

std::string quoted(const std::string& path) { return "'" + path + "'"; }

// Closes on every return path; close errors matter only for writes, which close explicitly.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() {
    int fd = fd_;
    fd_ = -1;
    return fd;
  }

 private:
  int fd_;
};

Status too_large(const std::string& path, uint64_t size, uint64_t max_bytes) {
  return capacity_exceeded("refusing to read " + quoted(path) + ": " + std::to_string(size) +
                           " bytes is more than the limit of " + std::to_string(max_bytes) + " bytes");
}

// Reads the whole file into buf (std::vector<uint8_t> or std::string).
template <class Buffer>
Status read_whole(const std::string& path, uint64_t max_bytes, Buffer& buf) {
  Fd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) {
    int err = errno;
    return io_error("cannot open " + quoted(path) + " for reading: " + errno_text(err));
  }
  struct stat st;
  if (::fstat(fd.get(), &st) != 0) {
    int err = errno;
    return io_error("cannot stat " + quoted(path) + ": " + errno_text(err));
  }
  if (S_ISDIR(st.st_mode)) return io_error("cannot read " + quoted(path) + ": it is a directory");

  // Regular files: trust st_size and check it before touching the data. Pipes and /proc files
  // report 0, so those are read in growing blocks with the limit checked as they come in.
  const bool sized = S_ISREG(st.st_mode) && st.st_size > 0;
  const uint64_t expect = sized ? static_cast<uint64_t>(st.st_size) : 0;
  if (expect > max_bytes) return too_large(path, expect, max_bytes);
  // 32-bit targets (armhf): the default 4 GiB limit is more than a size_t can hold.
  if (expect > static_cast<uint64_t>(SIZE_MAX / 2)) return too_large(path, expect, SIZE_MAX / 2);

  buf.resize(sized ? static_cast<size_t>(expect) : size_t(64) << 10);
  size_t got = 0;
  for (;;) {
    if (got == buf.size()) {
      if (sized) break;  // a file that grows while we read is returned as of its size at open
      if (buf.size() > SIZE_MAX / 4) return too_large(path, got, SIZE_MAX / 4);
      buf.resize(buf.size() * 2);
    }
    ssize_t r = ::read(fd.get(), &buf[got], buf.size() - got);
    if (r < 0) {
      if (errno == EINTR) continue;
      int err = errno;
      return io_error("cannot read " + quoted(path) + ": " + errno_text(err));
    }
    if (r == 0) break;
    got += static_cast<size_t>(r);
    if (got > max_bytes) return too_large(path, got, max_bytes);
  }
  buf.resize(got);  // a file that shrank while we read is returned as read
  return Status::Ok();
}

// Fault injection state (inject_write_fault): the armed call number (0: none) and the call count.
std::atomic<uint64_t> g_fault_at{0};
std::atomic<int> g_fault_kind{0};
std::atomic<uint64_t> g_write_calls{0};

std::string parent_dir(const std::string& path) {
  size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

}  // namespace

Expected<std::vector<uint8_t>> read_file(const std::string& path, uint64_t max_bytes) {
  std::vector<uint8_t> buf;
  Status s = read_whole(path, max_bytes, buf);
  if (!s.ok()) return s;
  return buf;
}

Expected<std::string> read_text_file(const std::string& path, uint64_t max_bytes) {
  std::string buf;
  Status s = read_whole(path, max_bytes, buf);
  if (!s.ok()) return s;
  return buf;
}

Status write_file_atomic(const std::string& path, const void* data, size_t size) {
  if (path.empty()) return invalid_argument("write_file_atomic: empty path");
  if (data == nullptr && size != 0) return invalid_argument("write_file_atomic: null data for " + quoted(path));

  // Same folder as the target, so rename() stays within one filesystem and is atomic. The pid keeps
  // two processes writing the same output from clobbering each other's temp file.
  const std::string tmp = path + ".tmp." + std::to_string(static_cast<long>(::getpid()));
  auto fail = [&](const std::string& what, int err) {
    ::unlink(tmp.c_str());
    return io_error("cannot write " + quoted(path) + ": " + what + ": " + errno_text(err));
  };

  Fd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666));
  if (fd.get() < 0) {
    int err = errno;
    // Nothing of ours to remove: open failed, and tmp may be someone else's (e.g. a directory).
    return io_error("cannot write " + quoted(path) + ": cannot create temporary file " + quoted(tmp) + ": " +
                    errno_text(err));
  }
  const uint64_t call = g_write_calls.fetch_add(1) + 1;
  const bool injected = call == g_fault_at.load();
  const auto fault = static_cast<WriteFault>(g_fault_kind.load());
  const char* p = static_cast<const char*>(data);
  size_t left = size;
  // An injected short write lets half of the bytes through, as a disk filling up mid-file does.
  size_t fail_after = injected && fault == WriteFault::kShortWrite ? size / 2 : SIZE_MAX;
  if (injected && fault == WriteFault::kNoSpace) fail_after = 0;
  while (left > 0 || fail_after == 0) {
    if (size - left >= fail_after) return fail("write to " + quoted(tmp) + " failed", ENOSPC);
    const size_t chunk = fail_after == SIZE_MAX ? left : std::min(left, fail_after - (size - left));
    ssize_t w = ::write(fd.get(), p, chunk);
    if (w < 0) {
      if (errno == EINTR) continue;
      return fail("write to " + quoted(tmp) + " failed", errno);
    }
    p += w;
    left -= static_cast<size_t>(w);
  }
  // fsync before rename: otherwise a crash can leave the new name pointing at an empty file.
  if (injected && fault == WriteFault::kIoError) return fail("fsync of " + quoted(tmp) + " failed", EIO);
  if (::fsync(fd.get()) != 0) return fail("fsync of " + quoted(tmp) + " failed", errno);
  // close() can report deferred write errors (NFS); never retry it, the fd is gone either way.
  if (::close(fd.release()) != 0) return fail("close of " + quoted(tmp) + " failed", errno);
  if (::rename(tmp.c_str(), path.c_str()) != 0) return fail("rename from " + quoted(tmp) + " failed", errno);

  // Persist the rename itself. Best effort: the data is already safe under one of the two names,
  // and some filesystems refuse fsync on directories.
  Fd dir(::open(parent_dir(path).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.get() >= 0) ::fsync(dir.get());
  return Status::Ok();
}

Status write_file_atomic(const std::string& path, const std::string& text) {
  return write_file_atomic(path, text.data(), text.size());
}

Status make_dirs(const std::string& path) {
  if (path.empty()) return invalid_argument("make_dirs: empty path");
  // Create each prefix ending before a '/', then the whole path. EEXIST is fine only for a
  // directory; a file in the way is reported by name.
  size_t pos = 0;
  for (;;) {
    size_t slash = path.find('/', pos);
    std::string prefix = slash == std::string::npos ? path : path.substr(0, slash);
    // Skip the root and runs of slashes ("/a//b/"): those prefixes are empty or already end in '/'.
    if (!prefix.empty() && prefix.back() != '/') {
      if (::mkdir(prefix.c_str(), 0777) != 0) {
        int err = errno;
        if (err != EEXIST) {
          return io_error("cannot create directory " + quoted(prefix) + " (for " + quoted(path) + "): " +
                          errno_text(err));
        }
        if (!is_directory(prefix)) {
          return io_error("cannot create directory " + quoted(path) + ": " + quoted(prefix) +
                          " exists and is not a directory");
        }
      }
    }
    if (slash == std::string::npos) break;
    pos = slash + 1;
  }
  return Status::Ok();
}

bool file_exists(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0;
}

bool is_directory(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

void inject_write_fault(uint64_t k, WriteFault kind) {
  g_fault_kind.store(static_cast<int>(kind));
  g_write_calls.store(0);
  g_fault_at.store(k);
}

uint64_t write_file_atomic_calls() { return g_write_calls.load(); }

Expected<FileLock> FileLock::acquire(const std::string& lock_path, const std::string& what) {
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
  if (fd < 0) {
    int err = errno;
    return io_error("cannot lock " + what + ": cannot open " + quoted(lock_path) + ": " + errno_text(err));
  }
  Fd guard(fd);
  for (;;) {
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) break;
    const int err = errno;
    if (err == EINTR) continue;
    if (err != EWOULDBLOCK) return io_error("cannot lock " + what + ": flock " + quoted(lock_path) + ": " + errno_text(err));
    char buf[32] = {};
    const ssize_t n = ::pread(fd, buf, sizeof(buf) - 1, 0);
    std::string pid = n > 0 ? std::string(buf, size_t(n)) : std::string();
    while (!pid.empty() && (pid.back() == '\n' || pid.back() == ' ')) pid.pop_back();
    return io_error(what + " is in use by another hbgs process" + (pid.empty() ? std::string() : " (pid " + pid + ")") +
                    "; wait for it to finish or use another folder (lock: " + quoted(lock_path) + ")");
  }
  // Best effort: the pid is only for the message above.
  const std::string pid = std::to_string(static_cast<long>(::getpid())) + "\n";
  if (::ftruncate(fd, 0) == 0) {
    ssize_t ignored = ::pwrite(fd, pid.data(), pid.size(), 0);
    (void)ignored;
  }
  return FileLock(guard.release());
}

FileLock& FileLock::operator=(FileLock&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}

FileLock::~FileLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the last descriptor releases the flock
}

std::string executable_path() {
  char buf[4096];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  return n > 0 ? std::string(buf, size_t(n)) : std::string();
}

}  // namespace gs::platform
