// SPDX-License-Identifier: MIT
// neon variants of the splatting kernels (compiled with neon flags; see simd/CMakeLists.txt).
// Everything inline this TU compiles lives in gs::simd::isa_neon (gs/simd/isa.h); set before any include.
#define GS_SIMD_ISA_NS isa_neon
#define GS_VARIANT_ARCH xsimd::neon
#define GS_VARIANT_NAME "neon"
#define GS_VARIANT_TABLE kernel_table_neon
#include "variant.inc"
