// SPDX-License-Identifier: MIT
// Monotonic clock for timings: steady_clock, so NTP steps and wall-clock changes never produce
// negative or inflated durations.
#include "gs/platform/clock.h"

#include <time.h>

#include <chrono>

namespace gs::platform {

uint64_t now_ns() {
  auto d = std::chrono::steady_clock::now().time_since_epoch();
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(d).count());
}

double now_seconds() {
  auto d = std::chrono::steady_clock::now().time_since_epoch();
  return std::chrono::duration<double>(d).count();
}

double process_cpu_seconds() {
  timespec ts;
  if (clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts) != 0) return 0;
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

}  // namespace gs::platform
