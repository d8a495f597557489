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
#
#   scripts/bench-register.sh --scenes [RUN_FOLDER...]   (default: /work/models/{synth,fox,snowmiku_plush}
#   or $HBGS_REGISTER_MODELS): the on-device protocol, one table row per scene: every test view from
#   an exact 10 deg / 10 % start (HBGS_BENCH_INIT, default 10), keyframe solver, finest level 1/4
#   (HBGS_BENCH_DOWNSCALE), 2 threads (HBGS_BENCH_THREADS): median rotation error, median
#   translation error (% of the scene radius), success (< 1 deg and < 1 %), verdict agreement
#   (`converged` exactly when successful), median wall and CPU-per-thread seconds per view; float and
#   fixed-point (--fixed-point) renders side by side.
#   Outputs out/bench_register/scenes/<scene>/ and out/bench_register/scenes/table.md.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

if [[ "${1:-}" == "--scenes" ]]; then
  shift
  models=("$@")
  if [[ ${#models[@]} -eq 0 ]]; then
    read -r -a models <<< "${HBGS_REGISTER_MODELS:-/work/models/synth /work/models/fox /work/models/snowmiku_plush}"
  fi
  cmake --preset release >/dev/null
  cmake --build --preset release -j"${GS_JOBS:-2}" --target bench_register
  bench=build/release/bench/bench_register
  out=out/bench_register/scenes
  mkdir -p "$out"
  init=${HBGS_BENCH_INIT:-10}
  ds=${HBGS_BENCH_DOWNSCALE:-4}
  table="$out/table.md"
  {
    echo "Registration, every test view from ${init} deg / $((init)) % of the radius, 1/${ds} resolution, keyframe solver, ${HBGS_BENCH_THREADS:-2} threads ($(date -u +%F), load $(cut -d' ' -f1 /proc/loadavg))"
    echo
    echo "| scene | renderer | views | median rotation (deg) | median translation (% radius) | success | verdict agreement | s/view (wall) | s/view (CPU / threads) |"
    echo "|---|---|---|---|---|---|---|---|---|"
  } > "$table"
  for m in "${models[@]}"; do
  for mode in float fixed-point; do
    name=$(basename "$m")
    flag=()
    [[ $mode == fixed-point ]] && flag=(--fixed-point)
    if [[ ! -e "$m" ]]; then echo "bench-register.sh: skipped $m (not found)" >&2; continue; fi
    name_m="$name/$mode"
    mkdir -p "$out/$name_m"
    # shellcheck disable=SC2086
    "$bench" --model "$m" --downscale "$ds" --init-errors "$init" --solvers keyframe --budgets default "${flag[@]}" \
      --threads "${HBGS_BENCH_THREADS:-2}" --out "$out/$name_m" --json "$out/$name_m/summary.json" ${HBGS_BENCH_REGISTER_ARGS:-} \
      > "$out/$name_m/table.txt" 2> "$out/$name_m/log.txt" || { cat "$out/$name_m/log.txt" >&2; exit 1; }
    python3 - "$out/$name_m/summary.json" "$name" "$mode" >> "$table" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); s = j["settings"][0]; t = j["threads"]
print(f"| {sys.argv[2]} | {sys.argv[3]} | {s['views']} | {s['median_final_rot_deg']:.3f} | {100 * s['median_final_trans_frac']:.2f} | "
      f"{100 * s['success_rate']:.0f} % | {100 * s['verdict_agreement_rate']:.0f} % | {s['median_ms'] / 1e3:.3f} | "
      f"{s['median_cpu_ms'] / t / 1e3:.3f} |")
PY
  done
  done
  cat "$table"
  exit 0
fi

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
