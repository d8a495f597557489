// SPDX-License-Identifier: MIT
// ThreadPool: fixed workers that wake on a generation word, claim chunks from an atomic counter and
// check back in, so a parallel_for costs a few atomics and (at most) one wake-up, and never allocates.
#include "gs/platform/thread_pool.h"

#include <sched.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace gs::platform {
namespace {

// The job word packs (generation << kParticipantBits) | participants into one atomic, so a worker
// learns in a single load both that a new job exists and whether it takes part. A worker that does
// not take part never reads the job fields, which the caller may already be rewriting.
constexpr int kParticipantBits = 16;
constexpr uint64_t kParticipantMask = (uint64_t(1) << kParticipantBits) - 1;
constexpr int kMaxThreads = 1024;  // far below kParticipantMask; more threads would only contend

// Polls before sleeping, so back-to-back loops skip the futex round trip. Short, and zero when the
// pool has more threads than CPUs: there a spinning thread steals the time slice of the thread that
// would finish the work.
constexpr int kSpinPolls = 2000;

inline void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__) || (defined(__arm__) && defined(__ARM_ARCH) && __ARM_ARCH >= 7)
  asm volatile("yield" ::: "memory");
#endif
}

// min(n, begin + grain) without overflowing when n and grain are both near SIZE_MAX.
inline size_t chunk_end(size_t begin, size_t grain, size_t n) { return begin + std::min(grain, n - begin); }

int available_cpus() {
  // Prefer the affinity mask: in containers and under taskset it is smaller than the CPUs online.
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof(set), &set) == 0) {
    int n = CPU_COUNT(&set);
    if (n > 0) return n;
  }
  unsigned hc = std::thread::hardware_concurrency();
  return hc > 0 ? static_cast<int>(hc) : 1;
}

}  // namespace

struct ThreadPool::Impl {
  int num_threads = 1;
  int spin_polls = kSpinPolls;
  std::vector<std::thread> workers;

  // Serialises parallel_for calls from different threads (see the note in parallel_for).
  std::mutex call_mutex;

  // Guards sleeping and waking only; the job itself is published through job_word.
  std::mutex m;
  std::condition_variable work_cv;
  std::condition_variable done_cv;
  bool stop = false;  // written under m, read by workers under m or after a job_word change

  std::atomic<uint64_t> job_word{0};
  std::atomic<size_t> next_chunk{0};
  std::atomic<int> pending{0};  // participating workers that have not checked in yet

  // The current job. Written by the caller before the release store of job_word and left alone
  // until every participant has checked in, so workers read them without locks.
  RangeFn fn = nullptr;
  void* ctx = nullptr;
  size_t n = 0;
  size_t grain = 1;
  size_t num_chunks = 0;

  void run_chunks(int worker) {
    for (;;) {
      size_t c = next_chunk.fetch_add(1, std::memory_order_relaxed);
      if (c >= num_chunks) return;
      size_t begin = c * grain;
      fn(ctx, begin, chunk_end(begin, grain, n), worker);
    }
  }

  void worker_main(int index);
  void wait_for_participants();
};

namespace {
// Which pool (if any) the current thread is working for, so a nested parallel_for on the same pool
// runs inline instead of waiting for workers that are busy running its parent.
thread_local const void* tl_pool = nullptr;
thread_local int tl_worker = 0;

// Marks the calling thread as worker 0 of a pool for the duration of its parallel_for.
class CurrentPool {
 public:
  explicit CurrentPool(const void* pool) : saved_pool_(tl_pool), saved_worker_(tl_worker) {
    tl_pool = pool;
    tl_worker = 0;
  }
  ~CurrentPool() {
    tl_pool = saved_pool_;
    tl_worker = saved_worker_;
  }
  CurrentPool(const CurrentPool&) = delete;
  CurrentPool& operator=(const CurrentPool&) = delete;

 private:
  const void* saved_pool_;
  int saved_worker_;
};
}  // namespace

void ThreadPool::Impl::worker_main(int index) {
  tl_pool = this;
  tl_worker = index;
  // Start from the constructor's value, not a fresh load: the first job may be published before
  // this thread gets to run, and it must still see it as new.
  uint64_t seen = 0;
  for (;;) {
    uint64_t word = job_word.load(std::memory_order_acquire);
    for (int i = 0; word == seen && i < spin_polls; ++i) {
      cpu_relax();
      word = job_word.load(std::memory_order_acquire);
    }
    if (word == seen) {
      std::unique_lock<std::mutex> lk(m);
      work_cv.wait(lk, [&] { return stop || job_word.load(std::memory_order_acquire) != seen; });
      if (stop) return;
      word = job_word.load(std::memory_order_acquire);
    }
    seen = word;
    // A worker may skip whole generations while asleep; only the latest one can still be waiting
    // for it, because the caller does not publish a new job before the previous one checked in.
    if (static_cast<uint64_t>(index) > (word & kParticipantMask)) continue;
    run_chunks(index);
    if (pending.fetch_sub(1, std::memory_order_acq_rel) == 1) {
      // Taking m orders this notify after the caller's predicate check, so the wake-up is not lost.
      std::lock_guard<std::mutex> lk(m);
      done_cv.notify_one();
    }
  }
}

void ThreadPool::Impl::wait_for_participants() {
  for (int i = 0; i < spin_polls; ++i) {
    if (pending.load(std::memory_order_acquire) == 0) return;
    cpu_relax();
  }
  std::unique_lock<std::mutex> lk(m);
  done_cv.wait(lk, [&] { return pending.load(std::memory_order_acquire) == 0; });
}

ThreadPool::ThreadPool(int num_threads) : impl_(new Impl) {
  const int cpus = available_cpus();
  int want = num_threads > 0 ? num_threads : cpus;
  want = std::min(want, kMaxThreads);
  impl_->spin_polls = want > cpus ? 0 : kSpinPolls;
  impl_->workers.reserve(static_cast<size_t>(want - 1));
  for (int i = 1; i < want; ++i) {
    // No exceptions leave the pool: if the OS refuses a thread (EAGAIN under a thread limit), keep
    // the ones we have; num_threads() reports the real count and parallel_for stays correct.
    try {
      impl_->workers.emplace_back([impl = impl_, i] { impl->worker_main(i); });
    } catch (const std::system_error&) {
      break;
    }
  }
  impl_->num_threads = 1 + static_cast<int>(impl_->workers.size());
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lk(impl_->m);
    impl_->stop = true;
  }
  impl_->work_cv.notify_all();
  for (std::thread& t : impl_->workers) t.join();
  delete impl_;
}

int ThreadPool::num_threads() const { return impl_->num_threads; }

void ThreadPool::parallel_for(size_t n, size_t grain, RangeFn fn, void* ctx) {
  if (n == 0) return;
  if (grain == 0) grain = 1;
  const size_t num_chunks = n / grain + (n % grain != 0);
  Impl& p = *impl_;

  // Nested call from inside a job of this pool (from a worker or from the calling thread): the
  // other workers are busy with the parent job, so waiting for them would deadlock. Run the chunks
  // serially on this thread under its own worker index instead.
  // Calls from other threads are serialised by call_mutex: the second caller blocks until the first
  // loop is done. Cycles across two pools (A's job calls B while B's job calls A) can still
  // deadlock and are not supported.
  if (tl_pool == &p) {
    for (size_t c = 0; c < num_chunks; ++c) {
      size_t begin = c * grain;
      fn(ctx, begin, chunk_end(begin, grain, n), tl_worker);
    }
    return;
  }

  // Held even on the inline path below: worker index 0 belongs to one caller at a time, since
  // callers use it to pick per-worker scratch.
  std::lock_guard<std::mutex> call_lock(p.call_mutex);
  CurrentPool mark(&p);
  if (p.num_threads == 1 || num_chunks == 1) {
    for (size_t c = 0; c < num_chunks; ++c) {
      size_t begin = c * grain;
      fn(ctx, begin, chunk_end(begin, grain, n), 0);
    }
    return;
  }

  // Wake no more workers than there are chunks beyond the caller's own.
  const int participants =
      static_cast<int>(std::min<size_t>(static_cast<size_t>(p.num_threads - 1), num_chunks - 1));
  p.fn = fn;
  p.ctx = ctx;
  p.n = n;
  p.grain = grain;
  p.num_chunks = num_chunks;
  p.next_chunk.store(0, std::memory_order_relaxed);
  p.pending.store(participants, std::memory_order_relaxed);
  {
    // Publishing under m pairs with the predicate check of sleeping workers (no lost wake-up).
    std::lock_guard<std::mutex> lk(p.m);
    uint64_t gen = (p.job_word.load(std::memory_order_relaxed) >> kParticipantBits) + 1;
    p.job_word.store((gen << kParticipantBits) | static_cast<uint64_t>(participants),
                     std::memory_order_release);
  }
  p.work_cv.notify_all();

  try {
    p.run_chunks(0);
  } catch (...) {
    // fn threw on the calling thread: workers may still be inside fn with ctx, so wait for them
    // before the exception unwinds ctx. (fn throwing on a worker thread calls std::terminate.)
    p.wait_for_participants();
    throw;
  }
  p.wait_for_participants();
}

}  // namespace gs::platform
