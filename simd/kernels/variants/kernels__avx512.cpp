// SPDX-License-Identifier: MIT
// avx512 variants of the splatting kernels (compiled with avx512 flags; see simd/CMakeLists.txt).
// Everything inline this TU compiles lives in gs::simd::isa_avx512 (gs/simd/isa.h); set before any include.
#define GS_SIMD_ISA_NS isa_avx512
#define GS_VARIANT_ARCH xsimd::avx512bw
#define GS_VARIANT_NAME "avx512"
#define GS_VARIANT_TABLE kernel_table_avx512
#include "variant.inc"
