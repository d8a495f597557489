#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Fisheye against its pinhole twin (issue 26), measured: `hbgs synth` (256x192 pinhole, the twin)
# and `hbgs synth --camera fisheye` of the same seed at FACTOR x the twin's width (the same 40
# views through a 180-degree equidistant lens), each trained for ITERATIONS with training seeds
# SEEDS; the fisheye at the twin's field of view and width (--fisheye-fov 58.088 --max-width 256),
# so both models see the same pinhole views. Both are evaluated on the twin's test views (the
# fisheye's model with `hbgs eval --dataset TWIN`): the same 5 ground-truth images for both. Prints
# every run's test PSNR and the means. The aim: the fisheye's mean within 0.5 dB of the twin's.
# Exits 1 when it is missed.
# Usage: scripts/fisheye-twin.sh [FACTOR=6] [ITERATIONS=3000] [SEEDS="1 2 3"] [WORK_DIR=out/fisheye_twin]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
factor=${1:-6}
iterations=${2:-3000}
seeds=${3:-"1 2 3"}
work=${4:-out/fisheye_twin}
cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=build/release/bin/hbgs
rm -rf "$work"
mkdir -p "$work"
"$hbgs" synth --out "$work/twin" --quiet
"$hbgs" synth --out "$work/fisheye" --camera fisheye --width $((256 * factor)) --height $((192 * factor)) --quiet
fov=$(python3 -c 'import math; print(2 * math.degrees(math.atan(128 / 230.5)))')  # the twin's focal: 0.9 x 256 -> 230.5
common=(--iterations "$iterations" --eval-every 0 --threads 2 --quiet)
for seed in $seeds; do
  "$hbgs" train "$work/twin" --out "$work/twin_$seed" --seed "$seed" "${common[@]}"
  "$hbgs" eval "$work/twin_$seed" --out "$work/twin_$seed/eval" --threads 2
  "$hbgs" train "$work/fisheye" --out "$work/fisheye_$seed" --seed "$seed" --fisheye-fov "$fov" --max-width 256 "${common[@]}"
  "$hbgs" eval "$work/fisheye_$seed" --dataset "$work/twin" --out "$work/fisheye_$seed/eval_on_twin" --threads 2
done
python3 - "$work" "$seeds" <<'PY'
import json, sys
work, seeds = sys.argv[1], sys.argv[2].split()
def psnr(path):
    return next(iter(json.load(open(path)).values()))["PSNR"]
twin = [psnr(f"{work}/twin_{s}/eval/results.json") for s in seeds]
fish = [psnr(f"{work}/fisheye_{s}/eval_on_twin/results.json") for s in seeds]
for s, t, f in zip(seeds, twin, fish):
    print(f"seed {s}: twin {t:.2f} dB, fisheye {f:.2f} dB ({f - t:+.2f})")
mt, mf = sum(twin) / len(twin), sum(fish) / len(fish)
print(f"mean: twin {mt:.2f} dB, fisheye {mf:.2f} dB ({mf - mt:+.2f}); aim: within 0.5 dB")
sys.exit(0 if mf > mt - 0.5 else 1)
PY
