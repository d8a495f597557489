#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Peak resident memory of the on-device path and of training, measured with /usr/bin/time -v:
#   scripts/measure-memory.sh [DATASET] [OUT]   (default ../shared/data/snowmiku_plush, out/memory)
# Trains DATASET to 1,000 iterations with hbgs-device (the peak of the whole run), makes the compact model
# file, then renders, registers (1/4 resolution, fixed point, from 10 deg / 10 %) and evaluates its
# test views with hbgs-device (the on-device commands, linked without FFmpeg / libcamera / Embree).
# Prints a table (MiB) and writes OUT/memory.csv. About 1 minute on 2 cores.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
dataset=${1:-../shared/data/snowmiku_plush}
out=${2:-out/memory}
threads=${HBGS_MEMORY_THREADS:-2}
if [[ ! -d "$dataset" ]]; then echo "measure-memory: dataset $dataset not found" >&2; exit 1; fi
if [[ ! -x /usr/bin/time ]]; then echo "measure-memory: /usr/bin/time is missing (apt install time)" >&2; exit 1; fi
cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs hbgs-device
hbgs=build/release/bin/hbgs
dev=build/release/bin/hbgs-device
mkdir -p "$out"
csv="$out/memory.csv"
echo "step,peak_rss_mib,seconds" >"$csv"

measure() {  # name command...
  local name=$1; shift
  local log="$out/$name.time"
  local rc=0
  /usr/bin/time -v -o "$log" "$@" >"$out/$name.log" 2>&1 || rc=$?
  # register exits 3 when a view's verdict is not converged (its results are written all the same)
  if [[ $rc -ne 0 && ! ( "$name" == register && $rc -eq 3 ) ]]; then
    echo "measure-memory: $name failed (exit $rc); see $out/$name.log" >&2
    exit 1
  fi
  local kb secs
  kb=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$log")
  secs=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$log")
  awk -v n="$name" -v kb="$kb" -v s="$secs" 'BEGIN { printf "%s,%.1f,%s\n", n, kb / 1024, s }' >>"$csv"
}

measure train "$dev" train "$dataset" --out "$out/run" --iterations 1000 --threads "$threads" --quiet --force
measure compact "$hbgs" compact "$out/run" --out "$out/run/model.hbgc" --threads "$threads" --no-eval
measure render "$dev" render "$out/run/model.hbgc" --dataset "$dataset" --split test --out "$out/render" --fixed-point --threads "$threads" --quiet
measure register "$dev" register "$out/run/model.hbgc" --dataset "$dataset" --views test --downscale 4 --fixed-point \
  --init-noise rot:10,trans:0.1 --out "$out/register" --threads "$threads" --quiet
measure eval "$dev" eval "$out/run/model.hbgc" --dataset "$dataset" --out "$out/eval" --fixed-point --threads "$threads"
echo "peak resident memory (MiB), $dataset, $threads threads:"
awk -F, '{ printf "  %-10s %14s %10s\n", $1, $2, $3 }' "$csv"
echo "written: $csv"
