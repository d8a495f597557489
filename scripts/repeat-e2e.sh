#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Runs the two COLMAP-driven end-to-end tests N times in a row each (default 20) from a configured
# build tree, stopping at the first failure, and prints every run's figures and duration: the check
# that they pass reliably, also under load (run a build alongside).
#   scripts/repeat-e2e.sh [N] [build dir, default build/release]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
n=${1:-20}
build=${2:-build/release}
log_dir=$(mktemp -d)
passed=0
t_all=$SECONDS
for ((i = 1; i <= n; ++i)); do
  for test in capture_pose_init_sfm_barf capture_ingest_synthetic_video; do
    t0=$SECONDS
    if ! ctest --test-dir "$build" -R "^${test}\$" -V >"$log_dir/$test.$i.log" 2>&1; then
      echo "run $i: $test FAILED after $((SECONDS - t0)) s (log: $log_dir/$test.$i.log)"
      tail -30 "$log_dir/$test.$i.log"
      echo "repeat-e2e: $passed passed before the first failure"
      exit 1
    fi
    if grep -q "Skipped\|Not Run" "$log_dir/$test.$i.log"; then
      echo "repeat-e2e: $test was skipped (COLMAP or FFmpeg missing?)"
      exit 1
    fi
    passed=$((passed + 1))
    # The figures each test prints (pose errors; ingest pose errors and PSNR).
    figures=$(grep -E "given poses:|test PSNR after|rotation" "$log_dir/$test.$i.log" | grep -v "^Test" | tail -2 | tr '\n' ' ')
    echo "run $i: $test passed in $((SECONDS - t0)) s: $figures"
  done
done
echo "repeat-e2e: all $passed runs passed ($n of each test) in $((SECONDS - t_all)) s; logs in $log_dir"
