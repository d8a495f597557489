// SPDX-License-Identifier: MIT
// Process-wide heap settings that keep resident memory close to what the program holds.
#pragma once

namespace gs::platform {

// Blocks of 128 KiB and more get their own pages from the OS and give them back when freed. (glibc
// otherwise raises that threshold to the largest block freed so far, so after the trainer's rows
// grow, later blocks of that size stay in the heap and freed ones keep their pages.) Call once,
// first thing in main; a no-op where the C library has no such setting. Returns whether it applied.
bool release_large_blocks_promptly();

}  // namespace gs::platform
