#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Builds the libFuzzer harnesses (fuzz/, clang with ASan + UBSan) and runs each on a copy of its seed
# corpus (fuzz/corpus/<harness>/):
#   scripts/fuzz.sh brief [seconds]    every harness for a few seconds (default 5): what CI runs
#   scripts/fuzz.sh long [runs]        every harness for a number of executions (default 1000000)
#   scripts/fuzz.sh long [runs] NAME.. only the named harnesses (colmap_text colmap_binary ply image
#                                      model compact checkpoint transforms point_ply video)
# Prints each harness's execution count, rate and new corpus entries; any crash, leak, UBSan report
# or timeout fails the script, and the input that caused it is kept (the path and the command that
# reproduces it are printed). Work goes to build/fuzz-work/ (not the repository).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
mode=${1:-brief}
shift || true
case "$mode" in
  brief) budget=(-max_total_time="${1:-5}") ;;
  long) budget=(-runs="${1:-1000000}") ;;
  *) echo "usage: $0 brief [seconds] | long [runs] [harness...]" >&2; exit 2 ;;
esac
shift || true
only=("$@")

jobs=${GS_JOBS:-2}
build=build/fuzz
t0=$SECONDS
if ! command -v clang++ >/dev/null; then
  echo "fuzz.sh: clang++ is not installed (scripts/install-deps.sh installs clang and libclang-rt-14-dev)" >&2
  exit 1
fi
CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DGS_BUILD_FUZZ=ON \
  -DGS_BUILD_TESTS=OFF -DGS_BUILD_BENCH=OFF -DGS_BUILD_APPS=OFF -DGS_WITH_EMBREE=OFF -DGS_WITH_LIBCAMERA=OFF -DCMAKE_UNITY_BUILD=ON >/dev/null
cmake --build "$build" -j"$jobs" --target fuzz_all
echo "fuzz.sh: configure + build took $((SECONDS - t0)) s"

read -r -a harnesses <"$build/fuzz_harnesses.txt" || true
IFS=';' read -r -a harnesses <<<"${harnesses[*]}"
if ((${#only[@]})); then harnesses=("${only[@]}"); fi
work=build/fuzz-work
mkdir -p "$work"
failed=0
for h in "${harnesses[@]}"; do
  bin="$build/fuzz/fuzz_$h"
  [[ -x "$bin" ]] || { echo "fuzz.sh: no harness $h (not built)" >&2; failed=1; continue; }
  corpus="$work/$h/corpus"
  artifacts="$work/$h/artifacts/"
  rm -rf "$work/$h"
  mkdir -p "$corpus" "$artifacts"
  cp fuzz/corpus/"$h"/* "$corpus"/
  seeds=$(ls "$corpus" | wc -l)
  t1=$SECONDS
  # -rss_limit_mb / -malloc_limit_mb: above the largest image hbgs accepts (16384 x 16384 RGBA, 1 GiB); a
  # parser that sizes buffers from a header must refuse a larger count before allocating.
  if ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:suppressions=$PWD/fuzz/ubsan.supp \
     "$bin" "$corpus" "${budget[@]}" -timeout=20 -rss_limit_mb=3072 -malloc_limit_mb=2048 \
     -artifact_prefix="$artifacts" -print_final_stats=1 >"$work/$h/log" 2>&1; then
    runs=$(grep -oE "stat::number_of_executed_units: *[0-9]+" "$work/$h/log" | grep -oE "[0-9]+$" || echo "?")
    secs=$((SECONDS - t1))
    rate=$(( secs > 0 && runs != 0 ? runs / secs : 0 )) 2>/dev/null || rate="?"
    echo "fuzz.sh: $h: $runs executions in $secs s (about $rate/s), corpus $seeds -> $(ls "$corpus" | wc -l) inputs, no finding"
  else
    failed=1
    echo "fuzz.sh: $h: FINDING (log: $work/$h/log)" >&2
    grep -E "ERROR|SUMMARY|runtime error|Test unit written" "$work/$h/log" | head -20 >&2
    for a in "$artifacts"*; do
      [[ -e "$a" ]] && echo "  reproduce: $bin $a" >&2
    done
  fi
done
echo "fuzz.sh: $mode run of ${#harnesses[@]} harnesses finished in $((SECONDS - t0)) s"
exit $failed
