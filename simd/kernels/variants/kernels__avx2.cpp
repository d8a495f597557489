// SPDX-License-Identifier: MIT
// avx2 variants of the splatting kernels (compiled with avx2 flags; see simd/CMakeLists.txt).
// Everything inline this TU compiles lives in gs::simd::isa_avx2 (gs/simd/isa.h); set before any include.
#define GS_SIMD_ISA_NS isa_avx2
#define GS_VARIANT_ARCH xsimd::fma3<xsimd::avx2>
#define GS_VARIANT_NAME "avx2"
#define GS_VARIANT_TABLE kernel_table_avx2
#include "variant.inc"
