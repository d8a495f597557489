// SPDX-License-Identifier: MIT
// neon variants of the splatting kernels (compiled with neon flags; see simd/CMakeLists.txt).
#define GS_VARIANT_ARCH xsimd::neon
#define GS_VARIANT_NAME "neon"
#define GS_VARIANT_TABLE kernel_table_neon
#include "variant.inc"
