#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# BARF's hard case on the built-in object capture (issue 15), measured: sigma 0.15 se(3) noise on
# every training pose, `--pose-init sfm --optimize-poses` on a white background, with the real
# COLMAP, at the full capture size (200x200, 48 views), against the same training from the true
# poses. The aims: training poses within 0.2 degrees of the truth (mean, Sim(3)-aligned) and the test
# PSNR within 0.5 dB of true-pose training (test views mapped into the model's frame and registered,
# as BARF evaluates). Exits 1 when an aim is missed. Not a CI test: COLMAP leaves the object's low
# ring unregistered and the frame it gives varies between runs (docs/POSES.md).
# Usage: scripts/object-barf.sh [ITERATIONS=3000] [WORK_DIR=out/object_barf]   (needs `colmap`)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
iterations=${1:-3000}
work=${2:-out/object_barf}
cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=build/release/bin/hbgs
if ! command -v colmap >/dev/null; then
  echo "object-barf: the 'colmap' command is not installed (scripts/install-deps.sh installs it)" >&2
  exit 2
fi
rm -rf "$work"
mkdir -p "$work"
"$hbgs" synth --object --out "$work/object" --quiet
common=(--iterations "$iterations" --background white --eval-every 0 --threads 2 --quiet)
"$hbgs" train "$work/object" --out "$work/true" "${common[@]}"
"$hbgs" train "$work/object" --out "$work/barf" "${common[@]}" --pose-noise barf:0.15 --optimize-poses --pose-init sfm
python3 - "$work/true/results.json" "$work/barf/results.json" "$iterations" <<'PY'
import json, sys
key = "ours_" + sys.argv[3]
truth = json.load(open(sys.argv[1]))[key]
barf = json.load(open(sys.argv[2]))[key]
p = barf["poses"]
sfm, final, given = p["sfm_init"], p["train_final"], p["train_input"]
print(f"given poses: {given['rotation_mean_deg']:.3f} deg; after SfM init: {sfm['errors']['rotation_mean_deg']:.3f} deg "
      f"({sfm['registered']} of {sfm['views']} registered); final: {final['rotation_mean_deg']:.3f} deg, "
      f"{100 * final['translation_mean_fraction_of_radius']:.3f} % of the radius; test PSNR {barf['PSNR']:.2f} dB against "
      f"{truth['PSNR']:.2f} dB from the true poses")
t = barf.get("test_pose_registration", {})
print(f"final median rotation {final['rotation_median_deg']:.3f} deg, max {final['rotation_max_deg']:.3f} deg; "
      f"held back at the end: {p['held_back']['still_held']}; test PSNR at the dataset poses {t.get('PSNR_at_dataset_poses', float('nan')):.2f} dB, "
      f"mapped {t.get('PSNR_at_mapped_poses', float('nan')):.2f} dB")
ok = (given["rotation_mean_deg"] > 10 and sfm["registered"] == sfm["views"] and final["rotation_mean_deg"] < 0.2
      and barf["PSNR"] > truth["PSNR"] - 0.5)
sys.exit(0 if ok else 1)
PY
