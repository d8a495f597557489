// SPDX-License-Identifier: MIT
// Reduced-size builds of the long tests, for the "qemu" label (cross builds run `ctest -L qemu` under
// qemu-user, and CI runs the qemu-labelled x86 binaries under qemu-x86_64 too). The same source is
// compiled twice (gs_add_test_pair in tests/CMakeLists.txt): test_x at full size for the native run,
// and test_x_qemu with GS_TEST_REDUCED=1, whose ctest names end in " (reduced)". The ASan build
// builds only the reduced one (GS_TEST_REDUCED_INSTEAD).
//
// What "reduced" may change: the number of seeds and repetitions, and which cases run (a case that
// is too slow under emulation and under ASan is marked GS_FULL_SIZE_ONLY and runs in the full-size
// build only; one that is slow under emulation alone is GS_NATIVE_ONLY, which the ASan build's
// reduced suites run too). It
// never changes a tolerance, a scene, an iteration count or a threshold: the reduced cases are the
// same checks on fewer draws. A test that needs a different size under emulation says so next to
// the size and states why its tolerance still holds.
#pragma once

#include <doctest/doctest.h>

#include <cstddef>
#include <initializer_list>
#include <vector>

#ifndef GS_TEST_REDUCED
#define GS_TEST_REDUCED 0
#endif
// 1 in the cross builds' reduced suites (run under qemu-user); 0 in the native ASan build's.
#ifndef GS_TEST_EMULATED
#define GS_TEST_EMULATED 0
#endif

namespace gs::test {

constexpr bool kReduced = GS_TEST_REDUCED != 0;
constexpr bool kEmulated = GS_TEST_EMULATED != 0;

// `all` in the full-size build; its first `reduced_count` entries in the reduced one.
template <class T>
std::vector<T> full_or_first(std::initializer_list<T> all, size_t reduced_count) {
  std::vector<T> v(all);
  if (kReduced && v.size() > reduced_count) v.resize(reduced_count);
  return v;
}

}  // namespace gs::test

// Decorator for a case that only the full-size build runs: TEST_CASE("..." * GS_FULL_SIZE_ONLY).
// (doctest leaves a skipped case out of --list-test-cases, so the reduced build registers no ctest
// entry for it; the native build runs it.)
#define GS_FULL_SIZE_ONLY doctest::skip(::gs::test::kReduced)
// Decorator for a case that is quick natively but too slow under emulation: the cross builds'
// reduced suites leave it out, the native reduced build (ASan: GS_TEST_REDUCED_INSTEAD) runs it.
#define GS_NATIVE_ONLY doctest::skip(::gs::test::kEmulated)
