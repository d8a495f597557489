#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# BARF's hard case on the built-in object capture (issue 15): sigma 0.15 se(3) noise on every
# training pose, `--pose-init sfm --optimize-poses` on a white background, with the real COLMAP,
# at the full capture size (200x200, 48 views: smaller captures leave COLMAP registering too few
# views) but a reduced training (400 iterations), against the same training from the true
# poses: the training poses must end within 0.2 degrees of the truth and the test PSNR within 0.5 dB
# of true-pose training. The full-size figures (200x200, 48 views, 3,000 iterations) are in the
# issue notes and docs/POSES.md. Needs the `colmap` command; without it the test is skipped (77).
# Usage: e2e_pose_init_sfm_object.sh HBGS WORK_DIR
set -euo pipefail
hbgs=$1
work=$2
if ! command -v colmap >/dev/null; then
  echo "SKIP: the 'colmap' command is not installed (scripts/install-deps.sh installs it)"
  exit 77
fi
rm -rf "$work"
mkdir -p "$work"
"$hbgs" synth --object --out "$work/object" --quiet
common=(--iterations 400 --background white --eval-every 0 --threads 2 --quiet)
"$hbgs" train "$work/object" --out "$work/true" "${common[@]}"
"$hbgs" train "$work/object" --out "$work/barf" "${common[@]}" --pose-noise barf:0.15 --optimize-poses --pose-init sfm
python3 - "$work/true/results.json" "$work/barf/results.json" <<'PY'
import json, sys
truth = json.load(open(sys.argv[1]))["ours_400"]
barf = json.load(open(sys.argv[2]))["ours_400"]
p = barf["poses"]
sfm, final, given = p["sfm_init"], p["train_final"], p["train_input"]
print(f"given poses: {given['rotation_mean_deg']:.3f} deg; after SfM init: {sfm['errors']['rotation_mean_deg']:.3f} deg "
      f"({sfm['registered']} of {sfm['views']} registered); final: {final['rotation_mean_deg']:.3f} deg, "
      f"{100 * final['translation_mean_fraction_of_radius']:.3f} % of the radius; test PSNR {barf['PSNR']:.2f} dB against "
      f"{truth['PSNR']:.2f} dB from the true poses")
ok = (given["rotation_mean_deg"] > 10 and sfm["registered"] == sfm["views"] and final["rotation_mean_deg"] < 0.2
      and barf["PSNR"] > truth["PSNR"] - 0.5)
sys.exit(0 if ok else 1)
PY
