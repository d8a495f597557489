// SPDX-License-Identifier: MIT
// Monotonic wall clock and process CPU time for timings and progress output.
#pragma once

#include <cstdint>

namespace gs::platform {

double now_seconds();  // monotonic, arbitrary origin
uint64_t now_ns();
// CPU time of this process, all threads, in seconds (0 where the clock is unavailable): a cost
// that other processes on the machine inflate far less than wall time.
double process_cpu_seconds();

}  // namespace gs::platform
