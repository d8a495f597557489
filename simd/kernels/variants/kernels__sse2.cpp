// SPDX-License-Identifier: MIT
// sse2 variants of the splatting kernels (compiled with sse2 flags; see simd/CMakeLists.txt).
// Everything inline this TU compiles lives in gs::simd::isa_sse2 (gs/simd/isa.h); set before any include.
#define GS_SIMD_ISA_NS isa_sse2
#define GS_VARIANT_ARCH xsimd::sse2
#define GS_VARIANT_NAME "sse2"
#define GS_VARIANT_TABLE kernel_table_sse2
#include "variant.inc"
