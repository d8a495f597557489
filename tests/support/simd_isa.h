// SPDX-License-Identifier: MIT
// One doctest case per SIMD instruction set, so that a missing ISA shows up as SKIPPED, never as
// passed (STYLE.md item 6: "A missing ISA means SKIP, not pass").
//
//   GS_SIMD_TEST_CASE(raster_matches_ref, "raster tile kernels match the reference") {
//     check(kt);  // kt: the const gs::simd::KernelTable* of this case's ISA
//   }
//
// registers "<name> / sse2", "<name> / avx2" and "<name> / avx512" on x86-64, "<name> / neon64" on
// AArch64 and "<name> / neon" on 32-bit ARM. A case whose ISA is not compiled in or not supported by
// the running CPU prints kSkipMarker and returns; gs_add_test (tests/CMakeLists.txt) gives every
// test SKIP_REGULAR_EXPRESSION on that marker, so ctest reports it as "Skipped". (doctest 2.4's
// skip() decorator would not do: a skipped case is left out of --list-test-cases, so ctest would not
// show it at all.) Run directly, the binary prints the marker and exits 0.
#pragma once

#include <doctest/doctest.h>

#include <string>

#include "gs/simd/kernel_table.h"

namespace gs::test {

// Printed by a case whose ISA is unavailable; matched by ctest's SKIP_REGULAR_EXPRESSION. Never
// print it from a case that also checks something: ctest would report such a case as skipped even
// if a check failed.
#define GS_TEST_SKIP_MARKER "[SKIPPED: "

// The table of `isa`, or nullptr after printing the skip marker when it is not compiled in or the
// CPU lacks it.
inline const gs::simd::KernelTable* simd_table_or_skip(const char* isa) {
  const gs::simd::KernelTable* kt = gs::simd::kernel_table_by_name(isa);
  // (std::string: doctest 2.4.9's MESSAGE prints a const char* operand as a pointer.)
  if (!kt) MESSAGE((std::string(GS_TEST_SKIP_MARKER) + isa + " kernels not compiled in or not supported by this CPU]"));
  return kt;
}

}  // namespace gs::test

#define GS_SIMD_ISA_CASE_(fn, name, isa)                                                     \
  TEST_CASE(name " / " isa) {                                                                \
    if (const gs::simd::KernelTable* gs_kt_ = ::gs::test::simd_table_or_skip(isa)) fn(gs_kt_); \
  }

#if defined(__x86_64__) || defined(_M_X64)
#define GS_SIMD_ISA_CASES_(fn, name) \
  GS_SIMD_ISA_CASE_(fn, name, "sse2") GS_SIMD_ISA_CASE_(fn, name, "avx2") GS_SIMD_ISA_CASE_(fn, name, "avx512")
#elif defined(__aarch64__) || defined(_M_ARM64)
#define GS_SIMD_ISA_CASES_(fn, name) GS_SIMD_ISA_CASE_(fn, name, "neon64")
#elif defined(__arm__) || defined(_M_ARM)
#define GS_SIMD_ISA_CASES_(fn, name) GS_SIMD_ISA_CASE_(fn, name, "neon")
#else
#define GS_SIMD_ISA_CASES_(fn, name)  // no SIMD kernels for this architecture: nothing to run or skip
#endif

// Declares fn(const KernelTable* kt), registers one case per ISA calling it, then opens fn's body.
#define GS_SIMD_TEST_CASE(fn, name)                       \
  static void fn(const gs::simd::KernelTable* kt);        \
  GS_SIMD_ISA_CASES_(fn, name)                            \
  static void fn([[maybe_unused]] const gs::simd::KernelTable* kt)

// As GS_SIMD_TEST_CASE, plus a "<name> / ref" case run on the reference table.
#define GS_REF_AND_SIMD_TEST_CASE(fn, name)                                 \
  static void fn(const gs::simd::KernelTable* kt);                          \
  TEST_CASE(name " / ref") { fn(&::gs::simd::ref_kernel_table()); }         \
  GS_SIMD_ISA_CASES_(fn, name)                                              \
  static void fn([[maybe_unused]] const gs::simd::KernelTable* kt)
