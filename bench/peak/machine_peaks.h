// SPDX-License-Identifier: MIT
// The machine's own peaks for bench_train --profile, measured in the same run: FMA throughput
// (the kernel table's vector width) on one core and on every pool thread, and copy bandwidth
// through memory (buffers much larger than the caches) on one core and on every pool thread.
#pragma once

#include <cstddef>
#include <string>

namespace gs::platform { class ThreadPool; }

namespace gs::bench {

struct MachinePeaks {
  std::string fma_isa;               // the loop's ISA: the kernel table's ("sse2" for "ref")
  double fma_gflops_core = 0;        // one thread
  double fma_gflops_all = 0;         // every pool thread at once
  double copy_gbs_core = 0;          // GB/s read + written by memcpy, one thread
  double copy_gbs_all = 0;           // ... every pool thread on its own slice
  size_t copy_buffer_bytes = 0;      // each of the source and destination
};

// kernel_isa: KernelTable::isa. Each of the four figures takes about `seconds` (the best of a few
// repetitions is kept: on a busy machine it is the least disturbed).
MachinePeaks measure_machine_peaks(const char* kernel_isa, platform::ThreadPool& pool, double seconds = 0.25);

}  // namespace gs::bench
