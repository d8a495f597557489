// SPDX-License-Identifier: MIT
// Tests for libgs_platform: parallel_for covers every index once and allocates nothing, the clock is
// monotonic, and file writes are atomic (a failed write leaves the old file and no temp file).
#include <doctest/doctest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/memory.h"
#include "gs/platform/process.h"
#include "gs/platform/thread_pool.h"
#include "support/alloc_counter.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using gs::platform::ThreadPool;

namespace {

// Records every index a parallel_for touched, and checks the chunk contract on the way.
struct Coverage {
  explicit Coverage(size_t n, size_t grain, int threads)
      : hits(new std::atomic<int>[n == 0 ? 1 : n]), n(n), grain(grain == 0 ? 1 : grain), threads(threads) {
    for (size_t i = 0; i < n; ++i) hits[i].store(0);
  }
  std::unique_ptr<std::atomic<int>[]> hits;
  size_t n;
  size_t grain;
  int threads;
  std::atomic<int> bad_chunks{0};
  std::atomic<int> bad_workers{0};

  static void run(void* ctx, size_t begin, size_t end, int worker) {
    auto* c = static_cast<Coverage*>(ctx);
    if (begin >= end || end > c->n || end - begin > c->grain) c->bad_chunks.fetch_add(1);
    if (worker < 0 || worker >= c->threads) c->bad_workers.fetch_add(1);
    for (size_t i = begin; i < end && i < c->n; ++i) c->hits[i].fetch_add(1);
  }
  size_t wrong_counts() const {
    size_t wrong = 0;
    for (size_t i = 0; i < n; ++i) wrong += hits[i].load() != 1;
    return wrong;
  }
};

using gs::test::TempDir;

// Names in dir that look like write_file_atomic's temp files for `name`.
std::vector<std::string> temp_files_for(const std::string& dir, const std::string& name) {
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(dir)) {
    std::string f = e.path().filename().string();
    if (f.rfind(name + ".tmp.", 0) == 0) found.push_back(f);
  }
  return found;
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

}  // namespace

TEST_CASE("parallel_for covers every index exactly once") {
  const int thread_counts[] = {1, 2, 3, 4, 8};
  const size_t sizes[] = {0, 1, 2, 7, 63, 64, 65, 1000, 4097};
  const size_t grains[] = {0, 1, 3, 64, 1000, 5000};
  for (int t : thread_counts) {
    ThreadPool pool(t);
    REQUIRE(pool.num_threads() == t);
    for (size_t n : sizes) {
      for (size_t g : grains) {
        CAPTURE(t);
        CAPTURE(n);
        CAPTURE(g);
        Coverage c(n, g, t);
        pool.parallel_for(n, g, &Coverage::run, &c);
        CHECK(c.wrong_counts() == 0);
        CHECK(c.bad_chunks.load() == 0);
        CHECK(c.bad_workers.load() == 0);
      }
    }
  }
}

TEST_CASE("for_each_index calls fn once per index, shared between the workers") {
  for (int t : {1, 3}) {
    ThreadPool pool(t);
    REQUIRE(pool.num_threads() == t);
    for (size_t n : {size_t(0), size_t(1), size_t(5), size_t(997)}) {
      std::vector<std::atomic<int>> hits(n);
      std::vector<std::thread::id> who(n);
      pool.for_each_index(n, [&](size_t i) {
        hits[i].fetch_add(1);
        who[i] = std::this_thread::get_id();
        // A slow first item: while its thread sleeps, the other workers take the rest.
        if (i == 0 && n > 1) std::this_thread::sleep_for(std::chrono::milliseconds(20));
      });
      int wrong = 0;
      for (auto& h : hits) wrong += h.load() != 1;
      CHECK(wrong == 0);
      if (t > 1 && n > 1) {
        size_t others = 0;
        for (size_t i = 1; i < n; ++i) others += who[i] != who[0];
        CHECK(others > 0);
      }
    }
  }
}

TEST_CASE("parallel_for chunk ends do not overflow near SIZE_MAX") {
  // Only the [begin, end) bookkeeping is checked; nothing is indexed.
  ThreadPool pool(2);
  const size_t n = SIZE_MAX;
  const size_t grain = SIZE_MAX / 2 + 1;  // two chunks, the second one short by one
  std::atomic<size_t> covered{0};
  std::atomic<int> bad{0};
  auto body = [&](size_t b, size_t e, int) {
    if (e <= b || e > n || e - b > grain) bad.fetch_add(1);
    covered.fetch_add(e - b);
  };
  pool.parallel_for(n, grain, body);
  CHECK(bad.load() == 0);
  CHECK(covered.load() == n);
}

TEST_CASE("parallel_for survives many back-to-back small jobs") {
  // Lost wake-ups or a worker claiming a chunk of the next job show up here as a hang or a miscount.
  ThreadPool pool(4);
  size_t wrong = 0;
  for (int rep = 0; rep < 2000; ++rep) {
    size_t n = static_cast<size_t>(rep % 13);
    Coverage c(n, 1, 4);
    pool.parallel_for(n, 1, &Coverage::run, &c);
    wrong += c.wrong_counts() + static_cast<size_t>(c.bad_chunks.load() + c.bad_workers.load());
  }
  CHECK(wrong == 0);
}

TEST_CASE("parallel_for allocates nothing after construction") {
  ThreadPool pool(4);
  std::vector<double> out(10000, 0.0);
  auto body = [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) out[i] += static_cast<double>(i);
  };
  pool.parallel_for(out.size(), 128, body);  // warm-up: first-touch of thread-locals etc.
  uint64_t allocations = 0;
  {
    gs::test::AllocationScope scope;
    for (int rep = 0; rep < 200; ++rep) pool.parallel_for(out.size(), 128, body);
    for (int rep = 0; rep < 200; ++rep) pool.parallel_for(3, 1, body);  // fewer chunks than workers
    allocations = scope.count();
  }
  CHECK(allocations == 0);
  CHECK(out[9999] == doctest::Approx(201.0 * 9999.0));  // warm-up + 200 full passes
}

TEST_CASE("parallel_for never gives one worker index to two threads at once") {
  // Callers index per-worker scratch by the worker argument; check it is exclusive, including when
  // two threads share the pool (their calls are serialised).
  ThreadPool pool(3);
  std::atomic<int> in_use[3] = {};
  std::atomic<int> clashes{0};
  std::atomic<size_t> items{0};
  auto body = [&](size_t b, size_t e, int w) {
    if (in_use[w].exchange(1) != 0) clashes.fetch_add(1);
    items.fetch_add(e - b);
    std::this_thread::yield();
    in_use[w].store(0);
  };
  auto hammer = [&] {
    for (int rep = 0; rep < 200; ++rep) pool.parallel_for(50, 2, body);
  };
  std::thread other(hammer);
  hammer();
  other.join();
  CHECK(clashes.load() == 0);
  CHECK(items.load() == 2u * 200u * 50u);
}

TEST_CASE("nested parallel_for runs inline instead of deadlocking") {
  ThreadPool pool(4);
  Coverage inner(64 * 16, 16, 4);
  auto outer = [&](size_t b, size_t e, int) {
    for (size_t i = b; i < e; ++i) {
      // Each outer index owns inner indices [16 i, 16 i + 16).
      auto part = [&](size_t ib, size_t ie, int w) { Coverage::run(&inner, 16 * i + ib, 16 * i + ie, w); };
      pool.parallel_for(16, 4, part);
    }
  };
  pool.parallel_for(64, 1, outer);
  CHECK(inner.wrong_counts() == 0);
  CHECK(inner.bad_workers.load() == 0);
}

TEST_CASE("default thread count is at least one") {
  ThreadPool pool;
  CHECK(pool.num_threads() >= 1);
  Coverage c(100, 7, pool.num_threads());
  pool.parallel_for(100, 7, &Coverage::run, &c);
  CHECK(c.wrong_counts() == 0);
}

TEST_CASE("clock is monotonic and in the right units") {
  uint64_t a = gs::platform::now_ns();
  double sa = gs::platform::now_seconds();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  uint64_t b = gs::platform::now_ns();
  double sb = gs::platform::now_seconds();
  CHECK(b > a);
  CHECK(b - a >= 19000000u);  // sleep_for never returns early; 1 ms slack for clock granularity
  CHECK(sb - sa >= 0.019);
  CHECK(sb - sa < 10.0);  // seconds, not ns or ms
}

TEST_CASE("write_file_atomic then read_file round trip") {
  TempDir dir;
  const std::string path = dir / "blob.bin";
  std::vector<uint8_t> data(70000);
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<uint8_t>((i * 131u) >> 3);
  data[5] = 0;  // embedded NULs must survive
  REQUIRE(gs::platform::write_file_atomic(path, data.data(), data.size()).ok());
  auto back = gs::platform::read_file(path);
  REQUIRE(back.ok());
  CHECK(*back == data);
  CHECK(temp_files_for(dir.path(), "blob.bin").empty());

  // Overwrite with shorter text, read as text.
  REQUIRE(gs::platform::write_file_atomic(path, std::string("short")).ok());
  auto text = gs::platform::read_text_file(path);
  REQUIRE(text.ok());
  CHECK(*text == "short");

  // Empty files are valid.
  REQUIRE(gs::platform::write_file_atomic(path, nullptr, 0).ok());
  auto empty = gs::platform::read_file(path);
  REQUIRE(empty.ok());
  CHECK(empty->empty());
}

TEST_CASE("write_file_atomic onto a directory fails and cleans up") {
  TempDir dir;
  const std::string target = dir / "out";
  REQUIRE(gs::platform::make_dirs(target).ok());
  REQUIRE(gs::platform::write_file_atomic(target + "/keep.txt", std::string("inside")).ok());

  gs::Status s = gs::platform::write_file_atomic(target, std::string("new content"));
  CHECK_FALSE(s.ok());
  CHECK(s.code() == gs::StatusCode::kIoError);
  CHECK(contains(s.message(), target));
  CHECK(temp_files_for(dir.path(), "out").empty());
  CHECK(gs::platform::is_directory(target));
  auto kept = gs::platform::read_text_file(target + "/keep.txt");
  REQUIRE(kept.ok());
  CHECK(*kept == "inside");
}

TEST_CASE("write_file_atomic failing mid-write keeps the old content") {
  // RLIMIT_FSIZE makes write() fail with EFBIG part-way through the temp file, a real mid-write
  // failure that also works as root (permission tricks do not).
  TempDir dir;
  const std::string path = dir / "model.ply";
  REQUIRE(gs::platform::write_file_atomic(path, std::string("old content")).ok());

  struct rlimit saved;
  REQUIRE(::getrlimit(RLIMIT_FSIZE, &saved) == 0);
  auto old_handler = ::signal(SIGXFSZ, SIG_IGN);  // else the kernel kills us instead of failing write()
  struct rlimit small = saved;
  small.rlim_cur = 4096;
  REQUIRE(::setrlimit(RLIMIT_FSIZE, &small) == 0);
  std::string big(100000, 'x');
  gs::Status s = gs::platform::write_file_atomic(path, big);
  ::setrlimit(RLIMIT_FSIZE, &saved);
  ::signal(SIGXFSZ, old_handler);

  CHECK_FALSE(s.ok());
  CHECK(contains(s.message(), path));
  CHECK(temp_files_for(dir.path(), "model.ply").empty());
  auto now = gs::platform::read_text_file(path);
  REQUIRE(now.ok());
  CHECK(*now == "old content");
}

TEST_CASE("write_file_atomic into a read-only folder fails and keeps the old content") {
  if (::geteuid() == 0) {
    MESSAGE("skipped: running as root, which ignores folder permissions");
    return;
  }
  TempDir dir;
  const std::string sub = dir / "ro";
  REQUIRE(gs::platform::make_dirs(sub).ok());
  const std::string path = sub + "/a.txt";
  REQUIRE(gs::platform::write_file_atomic(path, std::string("old")).ok());
  REQUIRE(::chmod(sub.c_str(), 0555) == 0);
  gs::Status s = gs::platform::write_file_atomic(path, std::string("new"));
  ::chmod(sub.c_str(), 0755);
  CHECK_FALSE(s.ok());
  CHECK(contains(s.message(), path));
  CHECK(temp_files_for(sub, "a.txt").empty());
  auto now = gs::platform::read_text_file(path);
  REQUIRE(now.ok());
  CHECK(*now == "old");
}

TEST_CASE("write_file_atomic into a missing folder names the path") {
  TempDir dir;
  const std::string path = dir / "no/such/dir/x.bin";
  gs::Status s = gs::platform::write_file_atomic(path, std::string("x"));
  CHECK_FALSE(s.ok());
  CHECK(contains(s.message(), path));
  CHECK_FALSE(gs::platform::file_exists(path));
}

TEST_CASE("read_file of a missing file names the path and the reason") {
  TempDir dir;
  const std::string path = dir / "missing.bin";
  auto r = gs::platform::read_file(path);
  REQUIRE_FALSE(r.ok());
  CHECK(r.status().code() == gs::StatusCode::kIoError);
  CHECK(contains(r.status().message(), path));
  CHECK(contains(r.status().message(), "No such file"));
  auto t = gs::platform::read_text_file(path);
  CHECK_FALSE(t.ok());
}

TEST_CASE("read_file of a directory is an error") {
  TempDir dir;
  auto r = gs::platform::read_file(dir.path());
  REQUIRE_FALSE(r.ok());
  CHECK(contains(r.status().message(), dir.path()));
}

TEST_CASE("read_file refuses files over max_bytes before reading") {
  TempDir dir;
  const std::string path = dir / "hundred.bin";
  REQUIRE(gs::platform::write_file_atomic(path, std::string(100, 'a')).ok());
  auto refused = gs::platform::read_file(path, 99);
  REQUIRE_FALSE(refused.ok());
  CHECK(refused.status().code() == gs::StatusCode::kCapacityExceeded);
  CHECK(contains(refused.status().message(), path));
  CHECK(contains(refused.status().message(), "100"));
  auto fits = gs::platform::read_file(path, 100);
  REQUIRE(fits.ok());
  CHECK(fits->size() == 100u);
  CHECK_FALSE(gs::platform::read_text_file(path, 10).ok());
}

TEST_CASE("read_file streams unsized files and enforces the limit") {
  // A FIFO reports no size, so read_file takes its growing-buffer path.
  ::signal(SIGPIPE, SIG_IGN);  // the writer sees EPIPE when the reader gives up early
  TempDir dir;
  const std::string fifo = dir / "pipe";
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  const size_t total = 300000;  // several times the initial 64 KiB block
  auto writer = [&] {
    int fd = ::open(fifo.c_str(), O_WRONLY);
    if (fd < 0) return;
    std::vector<char> block(10000, 'p');
    for (size_t sent = 0; sent < total;) {
      ssize_t w = ::write(fd, block.data(), block.size());
      if (w <= 0) break;
      sent += static_cast<size_t>(w);
    }
    ::close(fd);
  };
  {
    std::thread t(writer);
    auto r = gs::platform::read_file(fifo);
    t.join();
    REQUIRE(r.ok());
    CHECK(r->size() == total);
  }
  {
    std::thread t(writer);
    auto r = gs::platform::read_file(fifo, 100000);
    t.join();
    REQUIRE_FALSE(r.ok());
    CHECK(r.status().code() == gs::StatusCode::kCapacityExceeded);
    CHECK(contains(r.status().message(), fifo));
  }
}

TEST_CASE("make_dirs creates nested folders and is idempotent") {
  TempDir dir;
  const std::string nested = dir / "a/b//c/";
  REQUIRE(gs::platform::make_dirs(nested).ok());
  CHECK(gs::platform::is_directory(dir / "a/b/c"));
  CHECK(gs::platform::make_dirs(nested).ok());
  CHECK(gs::platform::make_dirs(dir.path()).ok());

  REQUIRE(gs::platform::write_file_atomic(dir / "a/file", std::string("f")).ok());
  gs::Status s = gs::platform::make_dirs(dir / "a/file/sub");
  CHECK_FALSE(s.ok());
  CHECK(contains(s.message(), dir / "a/file"));
  CHECK_FALSE(gs::platform::make_dirs("").ok());
}

TEST_CASE("file_exists and is_directory") {
  TempDir dir;
  const std::string f = dir / "f.txt";
  CHECK_FALSE(gs::platform::file_exists(f));
  REQUIRE(gs::platform::write_file_atomic(f, std::string("x")).ok());
  CHECK(gs::platform::file_exists(f));
  CHECK_FALSE(gs::platform::is_directory(f));
  CHECK(gs::platform::file_exists(dir.path()));
  CHECK(gs::platform::is_directory(dir.path()));
  CHECK_FALSE(gs::platform::is_directory(dir / "nope"));
}

TEST_CASE("run_process passes lines and exit codes and logs the output") {
  gs::test::TempDir tmp("gs_process");
  std::vector<std::string> lines;
  const std::string log = tmp / "run.log";
  gs::Expected<gs::platform::ProcessResult> r = gs::platform::run_process(
      {"sh", "-c", "echo first; echo 'to stderr' >&2; printf 'no newline'; exit 3"}, log,
      [&](const std::string& l) { lines.push_back(l); });
  REQUIRE(r.ok());
  CHECK(r->exit_code == 3);
  REQUIRE(lines.size() == 3);
  CHECK(lines[0] == "first");
  CHECK(lines[1] == "to stderr");
  CHECK(lines[2] == "no newline");
  gs::Expected<std::string> text = gs::platform::read_text_file(log);
  REQUIRE(text.ok());
  CHECK(text->find("$ sh -c") == 0);
  CHECK(text->find("to stderr") != std::string::npos);
  // Arguments reach the program unchanged (no shell in between).
  lines.clear();
  r = gs::platform::run_process({"sh", "-c", "echo \"$1\"", "sh", "a b; $HOME"}, "", [&](const std::string& l) { lines.push_back(l); });
  REQUIRE(r.ok());
  CHECK(r->exit_code == 0);
  REQUIRE(lines.size() == 1);
  CHECK(lines[0] == "a b; $HOME");
}

TEST_CASE("run_process reports a missing program and a killed one") {
  gs::Expected<gs::platform::ProcessResult> r = gs::platform::run_process({"gs-no-such-program-xyz"}, "");
  REQUIRE(!r.ok());
  CHECK(r.status().message().find("not found on PATH") != std::string::npos);
  CHECK(gs::platform::find_program("gs-no-such-program-xyz").empty());
  CHECK(!gs::platform::find_program("sh").empty());
  r = gs::platform::run_process({"sh", "-c", "kill -9 $$"}, "");
  REQUIRE(r.ok());
  CHECK(r->exit_code == 128 + 9);
}

// Under AddressSanitizer or ThreadSanitizer the sanitizer owns malloc and its mallopt does nothing:
// skipped there (doctest lists it as skipped), checked in every other build.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerAllocator = true;
#else
constexpr bool kSanitizerAllocator = false;
#endif
TEST_CASE("release_large_blocks_promptly applies on glibc" * doctest::skip(kSanitizerAllocator)) {
#if defined(__GLIBC__)
  CHECK(gs::platform::release_large_blocks_promptly());
#else
  CHECK_FALSE(gs::platform::release_large_blocks_promptly());
#endif
}
