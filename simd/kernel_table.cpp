// SPDX-License-Identifier: MIT
// Fills the kernel tables once: the reference table, and the SIMD tables compiled into this build
// that the running CPU supports (xsimd's CPUID / hwcap detection), best first.
#include "gs/simd/kernel_table.h"

#include <cstring>
#include <xsimd/xsimd.hpp>

#include "gs/simd/convert.h"
#include "gs/simd/loss.h"
#include "gs/simd/mlp.h"
#include "gs/simd/ref.h"

namespace gs::simd {

#define GS_DECLARE_VARIANT(name) const KernelTable* kernel_table_##name();
#if defined(GS_HAVE_AVX512)
GS_DECLARE_VARIANT(avx512)
#endif
#if defined(GS_HAVE_AVX2)
GS_DECLARE_VARIANT(avx2)
#endif
#if defined(GS_HAVE_SSE2)
GS_DECLARE_VARIANT(sse2)
#endif
#if defined(GS_HAVE_NEON64)
GS_DECLARE_VARIANT(neon64)
#endif
#if defined(GS_HAVE_NEON)
GS_DECLARE_VARIANT(neon)
#endif

const KernelTable& ref_kernel_table() {
  static const KernelTable table = {
      "ref", 1, &project_fwd_ref<float>, &project_bwd_ref<float>, &raster_fwd_tile_ref<float>,
      &raster_bwd_tile_ref<float>, &loss_fwd_ref<float>, &loss_bwd_ref<float>, &mlp_fwd_ref<float>,
      &mlp_bwd_ref<float>, &adam_step_ref<float>, &yuyv_to_rgb_ref, &nv12_to_rgb_ref, &qraster_fwd_tile_ref,
      &qmlp_fwd_ref, &loss_bwd_rows_ref<float>, &mlp_fwd_ref<float>,
  };
  return table;
}

namespace {

struct Registry {
  const KernelTable* tables[8];
  int count = 0;
  Registry() {
    const auto cpu = xsimd::available_architectures();
    (void)cpu;
#if defined(GS_HAVE_AVX512)
    if (cpu.avx512bw) tables[count++] = kernel_table_avx512();
#endif
#if defined(GS_HAVE_AVX2)
    if (cpu.avx2 && cpu.fma3_avx2) tables[count++] = kernel_table_avx2();
#endif
#if defined(GS_HAVE_SSE2)
    // SSE2 is part of x86-64 itself (GS_HAVE_SSE2 is only set there), like NEON on AArch64. Not
    // cpu.sse2: xsimd 8.1 reads it from CPUID.1 ECX bit 26 (XSAVE) instead of EDX bit 26, so a CPU
    // without XSAVE (Core 2, qemu -cpu core2duo) would get no SIMD table at all.
    tables[count++] = kernel_table_sse2();
#endif
#if defined(GS_HAVE_NEON64)
    tables[count++] = kernel_table_neon64();  // NEON is mandatory on AArch64
#endif
#if defined(GS_HAVE_NEON)
    if (cpu.neon) tables[count++] = kernel_table_neon();
#endif
  }
};

const Registry& registry() {
  static const Registry r;
  return r;
}

}  // namespace

int available_simd_kernel_tables(const KernelTable** out, int max_tables) {
  const Registry& r = registry();
  int n = 0;
  for (; n < r.count && n < max_tables; ++n) out[n] = r.tables[n];
  return n;
}

const KernelTable& best_kernel_table() {
  const Registry& r = registry();
  return r.count > 0 ? *r.tables[0] : ref_kernel_table();
}

const KernelTable* kernel_table_by_name(const char* isa) {
  if (std::strcmp(isa, "ref") == 0) return &ref_kernel_table();
  const Registry& r = registry();
  for (int i = 0; i < r.count; ++i)
    if (std::strcmp(r.tables[i]->isa, isa) == 0) return r.tables[i];
  return nullptr;
}

}  // namespace gs::simd
