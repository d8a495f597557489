#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The image-feature ablation (issue 24): every real scene in DATA, two seeds, the Scaffold-style
# baseline (--image-features none) against the paper's features and the visible-view variant:
#   scripts/ablation.sh [OUT] [DATA] [ITERATIONS]   (default out/ablation, ../shared/data, 7000)
# Each run trains with `hbgs train --iterations ITERATIONS` (test views every 8th, LPIPS-Alex when the
# weights are in DATA/lpips_alex); HBGS_ABLATION_BUDGET=60s adds the same grid under --time-budget.
# Resumable: a run whose results.json exists is kept and an interrupted one continues from its last
# checkpoint (every 1,000 iterations), so a stopped sweep goes on where it stopped. Writes OUT/ablation.md (mean and seed spread per scene and mode) and OUT/ablation.csv (one
# line a run). Long: 18 runs of 7,000 iterations are about an hour on 2 cores; start it in the
# background (nohup) and keep the machine otherwise idle if the ms per iteration matter.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=${1:-out/ablation}
data=${2:-../shared/data}
iterations=${3:-7000}
threads=${HBGS_ABLATION_THREADS:-2}
budget=${HBGS_ABLATION_BUDGET:-}
seeds=(0 1)
modes=(none paper visible)
source scripts/real-scenes.sh  # hbgs, scenes, lpips
mkdir -p "$out/runs"
out=$(realpath "$out")
settings=("it$iterations")
[[ -n "$budget" ]] && settings+=("budget$budget")
total=$(( ${#scenes[@]} * ${#seeds[@]} * ${#modes[@]} * ${#settings[@]} ))
n=0
for setting in "${settings[@]}"; do
  for scene in "${scenes[@]}"; do
    for mode in "${modes[@]}"; do
      for seed in "${seeds[@]}"; do
        n=$((n + 1))
        run="$out/runs/${scene}_${mode}_s${seed}_${setting}"
        if [[ -f "$run/results.json" ]]; then
          echo "ablation [$n/$total] $(basename "$run"): done before, kept"
          continue
        fi
        length=(--iterations "$iterations")
        [[ $setting == budget* ]] && length=(--iterations 30000 --time-budget "$budget")
        if [[ -f "$run/checkpoint.bin" ]]; then  # interrupted: continue from its last checkpoint
          echo "ablation [$n/$total] $(basename "$run"): resumed ($(date +%H:%M:%S))"
          "$hbgs" train "$data/$scene" --out "$run" --resume -q "${lpips[@]}" >> "$run.log" 2>&1 \
            || { echo "ablation: $(basename "$run") failed, see $run.log" >&2; exit 1; }
          continue
        fi
        echo "ablation [$n/$total] $(basename "$run") ($(date +%H:%M:%S))"
        "$hbgs" train "$data/$scene" --out "$run" "${length[@]}" --image-features "$mode" --seed "$seed" \
          --threads "$threads" --eval-every 0 --save-at '' --checkpoint-every 1000 -q --force "${lpips[@]}" \
          > "$run.log" 2>&1 || { echo "ablation: $(basename "$run") failed, see $run.log" >&2; exit 1; }
      done
    done
  done
done
python3 - "$out" <<'PY'
import csv, glob, json, os, statistics, sys
out = sys.argv[1]
rows = []
for path in sorted(glob.glob(os.path.join(out, "runs", "*", "results.json"))):
    name = os.path.basename(os.path.dirname(path))
    scene, rest = name.rsplit("_", 3)[0], name.rsplit("_", 3)[1:]
    mode, seed, setting = rest[0], rest[1][1:], rest[2]
    result = json.load(open(path))
    key = sorted(result)[-1]  # the final evaluation
    r = result[key]
    rows.append(dict(scene=scene, mode=mode, seed=seed, setting=setting, iterations=r["iterations"],
                     psnr=r["PSNR"], ssim=r["SSIM"], lpips=r.get("LPIPS"), gaussians=r["mean_gaussians_per_view"],
                     ms=r["median_iteration_ms"], train_s=r["train_seconds"]))
with open(os.path.join(out, "ablation.csv"), "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["scene"])
    w.writeheader()
    w.writerows(rows)
def cell(vals, fmt):
    if not vals: return "-"
    m = statistics.fmean(vals)
    return (fmt % m) + (" ± " + fmt % ((max(vals) - min(vals)) / 2) if len(vals) > 1 else "")
lines = ["| setting | scene | mode | runs | PSNR dB | SSIM | LPIPS-Alex | Gaussians/view | ms/iteration |",
         "|---|---|---|---:|---:|---:|---:|---:|---:|"]
for setting in sorted({r["setting"] for r in rows}):
    for scene in sorted({r["scene"] for r in rows}):
        for mode in ["none", "paper", "visible"]:
            g = [r for r in rows if r["setting"] == setting and r["scene"] == scene and r["mode"] == mode]
            if not g: continue
            lp = [r["lpips"] for r in g if r["lpips"] is not None]
            lines.append("| %s | %s | %s | %d | %s | %s | %s | %s | %s |" % (
                setting, scene, mode, len(g), cell([r["psnr"] for r in g], "%.3f"), cell([r["ssim"] for r in g], "%.4f"),
                cell(lp, "%.4f"), cell([r["gaussians"] for r in g], "%.0f"), cell([r["ms"] for r in g], "%.1f")))
lines.append("")
lines.append("Mean ± half the spread between seeds.")
open(os.path.join(out, "ablation.md"), "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
echo "written: $out/ablation.md, $out/ablation.csv"
