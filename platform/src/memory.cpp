// SPDX-License-Identifier: MIT
// Heap settings (gs/platform/memory.h): a fixed mmap threshold on glibc.
#include "gs/platform/memory.h"

#include <cstdlib>  // defines __GLIBC__ on glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace gs::platform {

bool release_large_blocks_promptly() {
#if defined(__GLIBC__)
  // Setting the threshold turns off glibc's dynamic adjustment of it (mallopt(3)).
  return mallopt(M_MMAP_THRESHOLD, 128 * 1024) == 1;
#else
  return false;
#endif
}

}  // namespace gs::platform
