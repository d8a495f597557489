// SPDX-License-Identifier: MIT
// neon64 variants of the splatting kernels (compiled with neon64 flags; see simd/CMakeLists.txt).
// Everything inline this TU compiles lives in gs::simd::isa_neon64 (gs/simd/isa.h); set before any include.
#define GS_SIMD_ISA_NS isa_neon64
#define GS_VARIANT_ARCH xsimd::neon64
#define GS_VARIANT_NAME "neon64"
#define GS_VARIANT_TABLE kernel_table_neon64
#include "variant.inc"
