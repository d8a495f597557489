#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# A start without SfM points (issue 24), at a reduced size: the transparent built-in object read from
# its transforms files (no point cloud) trained from points carved from the masks (the default), from
# random points in the cameras' common view (--no-carve-points), and from the COLMAP copy's SfM
# points; carved must come close to the SfM start and clearly beat the random one. The full-size
# figures are in docs/MODEL.md ("A start without SfM points"; scripts/object-masks-and-start.sh).
# Usage: e2e_object_start_train.sh HBGS WORK_DIR
set -euo pipefail
hbgs=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
"$hbgs" synth --object --out "$work/object" --width 96 --height 96 --views 24 --quiet
common=(--iterations 600 --background white --eval-every 0 --threads 2 --quiet)
"$hbgs" train "$work/object/transforms_train.json" --out "$work/run_carved" "${common[@]}"
"$hbgs" train "$work/object/transforms_train.json" --out "$work/run_random" --no-carve-points "${common[@]}"
"$hbgs" train "$work/object" --out "$work/run_sfm" "${common[@]}"
python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
r = {k: json.load(open(f"{work}/run_{k}/results.json"))["ours_600"] for k in ("carved", "random", "sfm")}
print("test PSNR: " + ", ".join(f"{k} {v['PSNR']:.2f} dB ({v['anchors']} anchors)" for k, v in r.items()))
# Measured (this size, 600 iterations, 2026-11-28): carved 26.87, random 25.09, SfM 28.14 dB (points
# where the rays enter the hull, without the photo-consistent depth: 22.45). Limits with margin from
# that run: carved at most 2 dB under the SfM start and at least 0.8 dB over the random one.
ok = r["carved"]["PSNR"] >= r["sfm"]["PSNR"] - 2.0 and r["carved"]["PSNR"] >= r["random"]["PSNR"] + 0.8
sys.exit(0 if ok else 1)
PY
