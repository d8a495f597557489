#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Fisheye cameras end to end at a reduced size (issue 26): `hbgs synth --camera fisheye` at 4x the
# width of its pinhole twin (64x48), trained at a 150-degree pinhole (whose top and bottom rows lie
# outside the fisheye image: pixels without a source, dropped from the loss) and at the twin's
# field of view; run.json records --fisheye-fov, and `hbgs eval` loads the run's dataset with it
# and also evaluates the model on the twin's test views. The full-size figures (6x the twin's
# width: 0.47 dB below the twin, mean of three seeds) are in README "Fisheye cameras".
# Usage: e2e_fisheye_train.sh HBGS WORK_DIR
set -euo pipefail
hbgs=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
"$hbgs" synth --out "$work/twin" --width 64 --height 48 --views-arc 8 --views-orbit 8 --points 1500 --quiet
"$hbgs" synth --out "$work/fish" --camera fisheye --width 256 --height 192 --views-arc 8 --views-orbit 8 --points 1500 --quiet
twin_fov=$(python3 -c 'import math; print(2 * math.degrees(math.atan(32 / 57.5)))')  # focal 0.9 x 64 -> 57.5
"$hbgs" train "$work/fish" --out "$work/run_wide" --iterations 300 --fisheye-fov 150 --max-width 128 --eval-every 0 --threads 2 --quiet
"$hbgs" train "$work/fish" --out "$work/run_twin" --iterations 300 --fisheye-fov "$twin_fov" --max-width 64 --eval-every 0 --threads 2 --quiet
"$hbgs" train "$work/twin" --out "$work/run_pin" --iterations 300 --eval-every 0 --threads 2 --quiet
"$hbgs" eval "$work/run_wide" --out "$work/eval_wide" --threads 2
"$hbgs" eval "$work/run_wide" --fisheye-fov 150 --out "$work/eval_wide_150" --threads 2
"$hbgs" eval "$work/run_wide" --fisheye-fov 0 --out "$work/eval_wide_auto" --threads 2
"$hbgs" eval "$work/run_twin" --dataset "$work/twin" --out "$work/eval_twin_on_pin" --threads 2
"$hbgs" eval "$work/run_pin" --out "$work/eval_pin" --threads 2
python3 - "$work" "$twin_fov" <<'PY'
import json, sys
work, twin_fov = sys.argv[1], float(sys.argv[2])
ok = True
run = json.load(open(f"{work}/run_wide/run.json"))
print(f"run_wide/run.json: fisheye_fov {run.get('fisheye_fov')}")
ok = ok and run.get("fisheye_fov") == 150 and run["options"].get("fisheye-fov") == 150
ok = ok and abs(json.load(open(f"{work}/run_twin/run.json"))["fisheye_fov"] - twin_fov) < 1e-9
def psnr(path):
    r = json.load(open(path))
    return next(iter(r.values()))["PSNR"]
wide, on_pin, pin = psnr(f"{work}/eval_wide/results.json"), psnr(f"{work}/eval_twin_on_pin/results.json"), psnr(f"{work}/eval_pin/results.json")
print(f"test PSNR: fisheye at 150 degrees on its own views {wide:.2f} dB; fisheye at the twin's field of view on the "
      f"twin's views {on_pin:.2f} dB; the twin {pin:.2f} dB")
# eval reads the run's field of view from run.json: the same as giving it, not the automatic one.
wide_150, wide_auto = psnr(f"{work}/eval_wide_150/results.json"), psnr(f"{work}/eval_wide_auto/results.json")
print(f"the 150-degree run evaluated with --fisheye-fov 150: {wide_150:.2f} dB, with the automatic 120: {wide_auto:.2f} dB")
ok = ok and wide_150 == wide and wide_auto != wide
# Limits from a measured run with margin (300 iterations, tiny views: far from converged): 11.16,
# 20.06 and 21.50 dB. A 150-degree pinhole 128 px wide is a hard view to train (its centre is 17 px
# of focal length, its edges stretched 15-fold); the limit only says that it trains.
ok = ok and wide > 8 and on_pin > 15 and on_pin > pin - 3
sys.exit(0 if ok else 1)
PY
