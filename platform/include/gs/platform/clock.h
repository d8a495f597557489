// SPDX-License-Identifier: MIT
// Monotonic wall clock for timings and progress output.
#pragma once

#include <cstdint>

namespace gs::platform {

double now_seconds();  // monotonic, arbitrary origin
uint64_t now_ns();

}  // namespace gs::platform
