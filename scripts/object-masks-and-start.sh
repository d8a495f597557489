#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Issue 24, items 4 and 5, at full size (hbgs synth --object defaults: 200x200, 48 views, 6 of them
# test views; 3,000 iterations): prints the figures docs/MODEL.md quotes.
#  - Masks: the cluttered object trained through its masks (white, random and black backgrounds)
#    against the same photos trained without masks (clutter and all), composited through the true
#    masks for evaluation (hbgs eval --composite-renders); PSNR inside the mask.
#  - A start without SfM points: the transparent object read from transforms_train.json (no point
#    cloud) from points carved from the masks (the default) and from random points
#    (--no-carve-points), against the COLMAP copy of the same views with its SfM points.
# Usage: scripts/object-masks-and-start.sh [OUT_DIR]   (default out/object_masks_start)
#        HBGS=path/to/hbgs THREADS=2 SEEDS="0 1" ITERATIONS=3000
# About 15 minutes per seed on two busy cores.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/object_masks_start}
hbgs=${HBGS:-build/release/bin/hbgs}
threads=${THREADS:-2}
seeds=${SEEDS:-0}
iterations=${ITERATIONS:-3000}
mkdir -p "$out"
[ -d "$out/cluttered" ] || "$hbgs" synth --object --object-background cluttered --out "$out/cluttered" --quiet
[ -d "$out/transparent" ] || "$hbgs" synth --object --out "$out/transparent" --quiet
if [ ! -d "$out/unmasked" ]; then
  mkdir -p "$out/unmasked"
  cp -r "$out/cluttered/images" "$out/cluttered/sparse" "$out/unmasked/"
fi
train() {  # NAME DATASET ARGS...
  local name=$1 data=$2
  shift 2
  [ -f "$out/runs/$name/results.json" ] && return 0
  "$hbgs" train "$data" --out "$out/runs/$name" --iterations "$iterations" --eval-every 0 --threads "$threads" --quiet --force "$@"
}
for s in $seeds; do
  train "masked_white_s$s" "$out/cluttered" --background white --seed "$s"
  train "masked_random_s$s" "$out/cluttered" --background random --seed "$s"
  train "masked_black_s$s" "$out/cluttered" --background black --seed "$s"
  train "unmasked_s$s" "$out/unmasked" --seed "$s"
  train "start_carved_s$s" "$out/transparent/transforms_train.json" --background white --seed "$s"
  train "start_random_s$s" "$out/transparent/transforms_train.json" --background white --no-carve-points --seed "$s"
  train "start_sfm_s$s" "$out/transparent" --background white --seed "$s"
  # Every masked figure on white: the random- and black-background runs and the unmasked one
  # (composited through the true masks) evaluated again on white.
  for r in masked_random masked_black; do
    [ -f "$out/runs/${r}_s$s/eval_white/results.json" ] ||
      "$hbgs" eval "$out/runs/${r}_s$s" --background white --out "$out/runs/${r}_s$s/eval_white" --threads "$threads" --quiet > /dev/null
  done
  [ -f "$out/runs/unmasked_s$s/eval_white/results.json" ] ||
    "$hbgs" eval "$out/runs/unmasked_s$s" --dataset "$out/cluttered" --background white --composite-renders \
      --out "$out/runs/unmasked_s$s/eval_white" --threads "$threads" --quiet > /dev/null
done
python3 - "$out" "$iterations" $seeds <<'PY'
import json, sys
out, iterations, seeds = sys.argv[1], sys.argv[2], sys.argv[3:]
def result(path):
    d = json.load(open(path))
    return d[f"ours_{iterations}"] if f"ours_{iterations}" in d else list(d.values())[-1]
print("| run | seed | test PSNR (white) | PSNR inside the mask | alpha IoU | anchors | train s |")
print("|---|---|---|---|---|---|---|")
for s in seeds:
    rows = [("masked, white", f"masked_white_s{s}", "results.json"),
            ("masked, random (evaluated on white)", f"masked_random_s{s}", "eval_white/results.json"),
            ("masked, black (evaluated on white)", f"masked_black_s{s}", "eval_white/results.json"),
            ("unmasked, composited through the masks", f"unmasked_s{s}", "eval_white/results.json"),
            ("transforms, carved points", f"start_carved_s{s}", "results.json"),
            ("transforms, random points", f"start_random_s{s}", "results.json"),
            ("COLMAP, SfM points", f"start_sfm_s{s}", "results.json")]
    for label, run, file in rows:
        r = result(f"{out}/runs/{run}/{file}")
        train = result(f"{out}/runs/{run}/results.json")
        print(f"| {label} | {s} | {r['PSNR']:.3f} | {r.get('PSNR_masked', -1):.3f} | {r.get('alpha_IoU', -1):.4f} | "
              f"{train['anchors']} | {train['train_seconds']:.1f} |")
PY
