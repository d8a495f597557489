// SPDX-License-Identifier: MIT
// sse2 variants of the splatting kernels (compiled with sse2 flags; see simd/CMakeLists.txt).
#define GS_VARIANT_ARCH xsimd::sse2
#define GS_VARIANT_NAME "sse2"
#define GS_VARIANT_TABLE kernel_table_sse2
#include "variant.inc"
