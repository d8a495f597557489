#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Runs the two COLMAP-driven end-to-end tests N times in a row each (default 20) from a configured
# build tree, stopping at the first failure, and prints every run's figures and duration: the check
# that they pass reliably, also under load (run a build alongside). A third argument runs only that
# test, so the two loops can run side by side:
#   scripts/repeat-e2e.sh [N] [build dir, default build/release] [capture_pose_init_sfm_barf|capture_ingest_synthetic_video]
# The per-run figures also go to <log dir>/figures.txt, one line per run, for the spreads.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
n=${1:-20}
build=${2:-build/release}
tests=(capture_pose_init_sfm_barf capture_ingest_synthetic_video)
[[ $# -ge 3 ]] && tests=("$3")
log_dir=$(mktemp -d)
passed=0
t_all=$SECONDS
for ((i = 1; i <= n; ++i)); do
  for test in "${tests[@]}"; do
    t0=$SECONDS
    log=$log_dir/$test.$i.log
    if ! ctest --test-dir "$build" -R "^${test}\$" -V >"$log" 2>&1; then
      echo "run $i: $test FAILED after $((SECONDS - t0)) s (log: $log)"
      grep -E "given poses:|test PSNR after|rotation error:|centre error:|consecutive frames:|SfM initialisation in|median move" "$log" || true
      tail -30 "$log"
      echo "repeat-e2e: $passed passed before the first failure; logs in $log_dir"
      exit 1
    fi
    if grep -q "Skipped\|Not Run" "$log"; then
      echo "repeat-e2e: $test was skipped (COLMAP or FFmpeg missing?)"
      exit 1
    fi
    passed=$((passed + 1))
    # The figures each test checks: the pose test's one summary line; the ingest test's pose errors
    # against the true path (compare-poses) and PSNR.
    if [[ $test == capture_pose_init_sfm_barf ]]; then
      figures=$(grep -o "given poses:.*" "$log" | tail -1)
    else
      figures=$(grep -oE "rotation error: mean [0-9.]+|centre error: +mean [0-9.]+ \([0-9.]+ %|consecutive frames: mean [0-9.]+|test PSNR after.*" "$log" |
                tr -s ' ' | tr '\n' ';')
    fi
    echo "run $i: $test passed in $((SECONDS - t0)) s: $figures" | tee -a "$log_dir/figures.txt"
  done
done
echo "repeat-e2e: all $passed runs passed ($n of each of ${tests[*]}) in $((SECONDS - t_all)) s; logs in $log_dir"
