#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# One training option against the defaults, on every scene, in one command: trains each scene with
# each variant (a name and the extra `hbgs train` arguments) and each seed, one run at a time, and
# writes out/option_sweep/sweep.csv (test PSNR / SSIM / LPIPS-Alex, training seconds, median
# iteration ms, anchors, Gaussians per view) and prints it with each variant's mean per scene.
#   scripts/option-sweep.sh [OUT]          (default out/option_sweep; finished runs are reused)
# Environment:
#   HBGS_SWEEP_VARIANTS  variants, one per line, "name: arguments" (default: "defaults:" and
#                        "coarse70: --coarse-fraction 0.7")
#   HBGS_SWEEP_SCENES    (default "snowmiku_plush fox synth"; synth is the built-in scene)
#   HBGS_SWEEP_SEEDS     (default "0"), HBGS_SWEEP_ITERATIONS (3000), HBGS_SWEEP_THREADS (2)
#   HBGS_BIN             the hbgs binary (default build/release/bin/hbgs, built if absent)
# Training seconds are the wall clock of a shared machine: compare variants run in one session, with
# nothing else running, and read them as ratios.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

out=${1:-out/option_sweep}
variants=${HBGS_SWEEP_VARIANTS:-$'defaults:\ncoarse70: --coarse-fraction 0.7'}
scenes=${HBGS_SWEEP_SCENES:-snowmiku_plush fox synth}
seeds=${HBGS_SWEEP_SEEDS:-0}
iterations=${HBGS_SWEEP_ITERATIONS:-3000}
threads=${HBGS_SWEEP_THREADS:-2}
hbgs=${HBGS_BIN:-build/release/bin/hbgs}
if [[ -z "${HBGS_BIN:-}" ]]; then
  cmake --preset release >/dev/null
  cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
fi
mkdir -p "$out"

source scripts/scene-dataset.sh

csv=$out/sweep.csv
echo "scene,variant,seed,psnr,ssim,lpips,train_seconds,median_iteration_ms,anchors,gaussians_per_view" > "$csv.tmp"
for scene in $scenes; do
  dataset=$(scene_dataset "$scene" "$out/synth_scene")
  if [[ ! -d "$dataset" ]]; then
    echo "option-sweep.sh: skipped $scene: $dataset not found (../shared is absent)" >&2
    continue
  fi
  for seed in $seeds; do
    while IFS= read -r line; do
      [[ -z "$line" ]] && continue
      name=${line%%:*}
      args=${line#*:}
      run=$out/$scene/${name}_s$seed
      if [[ ! -f "$run/results.json" ]] || ! grep -q "\"ours_$iterations\"" "$run/results.json"; then
        echo "option-sweep.sh: $(date +%T) $scene, $name (${args# }), seed $seed, $iterations iterations" >&2
        # shellcheck disable=SC2086  # the variant's arguments are split on purpose
        "$hbgs" train "$dataset" --out "$run" --iterations "$iterations" --seed "$seed" --threads "$threads" \
          --eval-every 0 --force --quiet $args
      fi
      python3 - "$scene" "$name" "$seed" "$run/results.json" "ours_$iterations" >> "$csv.tmp" <<'EOF'
import json, sys
scene, name, seed, path, key = sys.argv[1:6]
m = json.load(open(path))[key]
print(",".join([scene, name, seed, "%.3f" % m["PSNR"], "%.4f" % m["SSIM"], "%.4f" % m.get("LPIPS", float("nan")),
                "%.1f" % m["train_seconds"], "%.2f" % m["median_iteration_ms"], str(m["anchors"]),
                "%.0f" % m["mean_gaussians_per_view"]]))
EOF
    done <<< "$variants"
  done
done
mv "$csv.tmp" "$csv"
column -s, -t "$csv"
python3 - "$csv" <<'EOF'
import csv, sys, collections
rows = list(csv.DictReader(open(sys.argv[1])))
acc = collections.defaultdict(list)
for r in rows: acc[(r["scene"], r["variant"])].append(r)
print("\nmeans per scene and variant (PSNR dB, train s):")
for (scene, variant), rs in acc.items():
    n = len(rs)
    print("  %-16s %-16s %d run(s)  %.3f dB  %.1f s" % (scene, variant, n, sum(float(r["psnr"]) for r in rs) / n,
                                                     sum(float(r["train_seconds"]) for r in rs) / n))
EOF
