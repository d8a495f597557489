#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Masks that do not cost the object (issue 24), at a reduced size: the cluttered built-in object
# trained through its masks on white, against the same photos trained without masks (the clutter
# and all) and composited through the true masks afterwards (hbgs eval --composite-renders); the
# PSNR inside the mask of the masked run must not be lower. The full-size figures are in
# docs/MODEL.md ("Backgrounds and masks"; scripts/object-masks-and-start.sh).
# Usage: e2e_object_masks_train.sh HBGS WORK_DIR
set -euo pipefail
hbgs=$1
work=$2
rm -rf "$work"
mkdir -p "$work/unmasked"
"$hbgs" synth --object --object-background cluttered --out "$work/cluttered" --width 96 --height 96 --views 24 --quiet
cp -r "$work/cluttered/images" "$work/cluttered/sparse" "$work/unmasked/"
common=(--iterations 600 --eval-every 0 --threads 2 --quiet)
"$hbgs" train "$work/cluttered" --out "$work/run_masked" --background white "${common[@]}"
"$hbgs" train "$work/unmasked" --out "$work/run_unmasked" "${common[@]}"
"$hbgs" eval "$work/run_unmasked" --dataset "$work/cluttered" --background white --composite-renders --out "$work/eval_unmasked" \
  --threads 2 --quiet
python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
masked = json.load(open(f"{work}/run_masked/results.json"))["ours_600"]
unmasked = list(json.load(open(f"{work}/eval_unmasked/results.json")).values())[-1]
print(f"inside the mask: masked run {masked['PSNR_masked']:.2f} dB, unmasked run composited through the masks "
      f"{unmasked['PSNR_masked']:.2f} dB")
# Measured (this size, 600 iterations, 2026-11-28): 24.00 against 15.15 dB. The check asks for at
# least 3 dB more (a third of the measured lead), so the lead must hold, not just its sign, and the
# masked run must stay near its figure.
sys.exit(0 if masked["PSNR_masked"] >= unmasked["PSNR_masked"] + 3.0 and masked["PSNR_masked"] > 22.0 else 1)
PY
