#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# BARF's hard case on the built-in object capture (issue 15), measured: sigma 0.15 se(3) noise on
# every training pose, `--pose-init sfm --optimize-poses` on a white background, with the real
# COLMAP, at the full capture size (200x200, 48 views), against the same training from the true
# poses. The aims: training poses within 0.2 degrees of the truth (mean, Sim(3)-aligned) and the test
# PSNR within 0.5 dB of true-pose training (test views mapped into the model's frame and registered,
# as BARF evaluates). Exits 1 when an aim is missed. Not a CI test: COLMAP leaves the object's low
# ring unregistered and the frame it gives varies between runs (docs/POSES.md).
# Views SfM cannot register, or that the SfM points contradict, are held back and repaired by
# registration or kept out (docs/POSES.md "Every view earns its place"); the pose aim is over the
# views trained on at the end, and the views kept out are listed. RUNS repeats the noisy run (COLMAP
# differs between runs), the true-pose training runs once.
# Usage: scripts/object-barf.sh [ITERATIONS=3000] [WORK_DIR=out/object_barf] [RUNS=1]   (needs `colmap`)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
iterations=${1:-3000}
work=${2:-out/object_barf}
runs=${3:-1}
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
failed=0
for ((run = 1; run <= runs; ++run)); do
  out=$work/barf$run
  "$hbgs" train "$work/object" --out "$out" "${common[@]}" --pose-noise barf:0.15 --optimize-poses --pose-init sfm
  python3 - "$work/true/results.json" "$out/results.json" "$iterations" "$run" <<'PY' || failed=1
import json, sys
key = "ours_" + sys.argv[3]
truth = json.load(open(sys.argv[1]))[key]
barf = json.load(open(sys.argv[2]))[key]
p = barf["poses"]
sfm, final, given, held = p["sfm_init"], p["train_final"], p["train_input"], p["held_back"]
still = set(held["still_held"])
trained = [d for n, d in final["per_view_rotation_deg"].items() if n not in still]
trained_mean = sum(trained) / max(len(trained), 1)
print(f"run {sys.argv[4]}: given poses {given['rotation_mean_deg']:.3f} deg; after SfM init {sfm['errors']['rotation_mean_deg']:.3f} deg "
      f"({sfm['registered']} of {sfm['views']} registered); final {final['rotation_mean_deg']:.3f} deg over all views "
      f"(max {final['rotation_max_deg']:.3f}), {trained_mean:.3f} deg over the {len(trained)} views trained on at the end, "
      f"{100 * final['translation_mean_fraction_of_radius']:.3f} % of the radius; test PSNR {barf['PSNR']:.2f} dB against "
      f"{truth['PSNR']:.2f} dB from the true poses")
print(f"  held back at the start: {held['at_start']} (not registered by SfM {held['not_registered_by_sfm']}, contradicted by the "
      f"points {held['contradicted_by_points']}); repaired {held['repaired']}; kept out {sorted(still)}")
# The aims: every view trained on within 0.2 degrees on average (a view no registration places stays
# out of training and is reported, never trained at a wrong pose), and the test PSNR within 0.5 dB.
ok = given["rotation_mean_deg"] > 10 and trained_mean < 0.2 and barf["PSNR"] > truth["PSNR"] - 0.5
sys.exit(0 if ok else 1)
PY
done
exit $failed
