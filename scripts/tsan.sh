#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# ThreadSanitizer job: builds the thread pool, renderer, trainer and registration tests with
# -fsanitize=thread (g++ 12 and its libtsan, build/tsan) and runs them; any data race fails the
# script. (clang's static TSan runtime defines operator new, which the tests' allocation counter
# also replaces; g++'s shared runtime lets the test's definition win.)
#   scripts/tsan.sh
# The trainer and registration suites are their reduced-size builds (support/reduced.h, as under
# qemu): TSan makes code 5-15x slower, and the reduced cases still run every threaded path with a
# 2-thread pool (the thread pool itself is checked with up to 8 threads).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
jobs=${GS_JOBS:-2}
build=build/tsan
t0=$SECONDS
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGS_SANITIZE_THREAD=ON \
  -DGS_BUILD_BENCH=OFF -DGS_BUILD_APPS=OFF -DGS_WITH_EMBREE=OFF -DGS_WITH_LIBCAMERA=OFF -DGS_WITH_LIBAV=OFF \
  -DGS_TEST_REDUCED_SUITES=ON -DCMAKE_UNITY_BUILD=ON >/dev/null
suites=(test_platform test_render test_trainer_qemu test_register_qemu)
cmake --build "$build" -j"$jobs" --target "${suites[@]}"
echo "tsan.sh: configure + build took $((SECONDS - t0)) s"

export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 exitcode=66"
failed=0
for s in "${suites[@]}"; do
  bin=$(find "$build/tests" -type f -name "$s" -perm -u+x | head -1)
  t1=$SECONDS
  if (cd "$PWD" && "$bin" --no-intro >"$build/$s.log" 2>&1); then
    echo "tsan.sh: $s passed with no data race in $((SECONDS - t1)) s ($(grep -oE 'test cases: *[0-9]+' "$build/$s.log" | head -1))"
  else
    failed=1
    echo "tsan.sh: $s FAILED (log: $build/$s.log)" >&2
    grep -E "WARNING: ThreadSanitizer|SUMMARY|ERROR|FAILED|Status" -A12 "$build/$s.log" | head -60 >&2
  fi
done
echo "tsan.sh: finished in $((SECONDS - t0)) s"
exit $failed
