#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Registration speed against accuracy in one command: builds bench_register (release preset),
# trains a model on ../shared/data/snowmiku_plush (2000 iterations; reused from
# out/bench_register/model/ when present) unless a model is given, then sweeps start error x solver
# x iteration budget over the test views and writes out/bench_register/{register_sweep.csv,
# register_summary.csv, time_vs_error.svg, success_vs_init.svg, summary.json}.
#   scripts/bench-register.sh [RUN_FOLDER | MODEL.hbgs]   (extra bench_register options via
#   HBGS_BENCH_REGISTER_ARGS, e.g. "--downscale 2 --init-errors 5,10"; GS_JOBS: build jobs, default 2;
#   HBGS_BENCH_TRAIN_ITERATIONS: training iterations when a model is trained, default 2000)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

model=${1:-}
dataset=${HBGS_BENCH_DATASET:-../shared/data/snowmiku_plush}
out=out/bench_register
if [[ -z "$model" && ! -d "$dataset" ]]; then
  echo "bench-register.sh: skipped: $dataset not found (../shared is absent); pass a run folder or .hbgs model" >&2
  exit 0
fi

cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target bench_register
bench=build/release/bench/bench_register
mkdir -p "$out"

args=(--downscale 4 --out "$out" --json "$out/summary.json")
if [[ -n "$model" ]]; then
  args+=(--model "$model")
elif [[ -f "$out/model/model.hbgs" ]]; then
  echo "bench-register.sh: reusing $out/model/model.hbgs (delete it to train again)"
  args+=(--model "$out/model/model.hbgs" --dataset "$dataset")
else
  args+=(--dataset "$dataset" --train-iterations "${HBGS_BENCH_TRAIN_ITERATIONS:-2000}"
         --save-model "$out/model/model.hbgs")
fi
# shellcheck disable=SC2086
"$bench" "${args[@]}" ${HBGS_BENCH_REGISTER_ARGS:-}
