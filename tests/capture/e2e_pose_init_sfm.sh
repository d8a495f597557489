#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `hbgs train --optimize-poses --pose-init sfm` from BARF's hard case (sigma 0.15 se(3) noise on
# every training pose, about 14.6 degrees) on the built-in scene, with the real COLMAP: the views
# trained on at the end must be within 0.2 degrees and 0.5 % of the radius of the truth on average, and at most 3 views kept
# out of training. A short run (200 iterations); the full figures are in the issue notes and POSES.md.
# Needs the `colmap` command; without it the test says so and is skipped (exit 77).
# Usage: e2e_pose_init_sfm.sh HBGS WORK_DIR
set -euo pipefail
hbgs=$1
work=$2
if ! command -v colmap >/dev/null; then
  echo "SKIP: the 'colmap' command is not installed (scripts/install-deps.sh installs it)"
  exit 77
fi
rm -rf "$work"
mkdir -p "$work"
"$hbgs" synth --out "$work/scene" --quiet
"$hbgs" train "$work/scene" --out "$work/run" --iterations 200 --pose-noise barf:0.15 --optimize-poses \
  --pose-init sfm --eval-every 0 --threads 2
# A failed check keeps the run's results (a rerun of the test clears the work folder): the cause of
# a rare failure must not be lost with it.
keep_on_failure() {
  local kept="$work.failed-$(date +%Y%m%d-%H%M%S)"
  mkdir -p "$kept" && cp -r "$work/run/results.json" "$work/run/progress.json" "$work/run/per_view.json" "$work/run/sfm_init" "$kept/" 2>/dev/null || true
  echo "FAILED: the run's results are kept in $kept"
}
trap keep_on_failure ERR
python3 - "$work/run/results.json" <<'PY'
import json, sys
r = next(iter(json.load(open(sys.argv[1])).values()))["poses"]
sfm, final, given, held = r["sfm_init"], r["train_final"], r["train_input"], r["held_back"]
align = r["point_alignment"]
still = set(held["still_held"])
rot = [d for n, d in final["per_view_rotation_deg"].items() if n not in still]
trained_mean = sum(rot) / max(len(rot), 1)
trans = [d for n, d in final["per_view_translation"].items() if n not in still]
trained_trans = sum(trans) / max(len(trans), 1) / r["scene_radius"]
print(f"given poses: {given['rotation_mean_deg']:.3f} deg; after SfM init: {sfm['errors']['rotation_mean_deg']:.3f} deg "
      f"({sfm['registered']} of {sfm['views']} registered, SfM attempts {sfm.get('attempts', 1)}); after point alignment: "
      f"{align['errors']['rotation_mean_deg']:.3f} deg (median move {align.get('median_move_deg', float('nan')):.3f} deg); "
      f"final: {final['rotation_mean_deg']:.3f} deg over all views, {trained_mean:.3f} deg over the {len(rot)} trained on, "
      f"{100 * trained_trans:.3f} % of the radius (trained on); held back {held['at_start']} "
      f"(contradicted by the points {held['contradicted_by_points']}, not registered {held['not_registered_by_sfm']}, "
      f"doubted by the SfM check {held['doubted_by_sfm_check']}, moved far by the point alignment {held['moved_far_by_point_alignment']}), "
      f"repaired {held['repaired']}, kept out {sorted(still)}")
# Limits from measured spreads (2 cores, a build and other tests alongside; 19 SfM attempts over
# 15 runs). When COLMAP's reconstruction is sound (0.75-1.16 degrees after SfM), the point alignment
# lands on the same optimum every time: 0.047-0.050 degrees and 0.058-0.060 % of the radius at the
# end. When it is not (4 of the 19 attempts before issue 26; COLMAP's features and matches differ
# from run to run whatever the seed and thread count, docs/CAPTURE.md), views ended at wrong
# poses (final 0.39, 3.1, 5.5 and 6.1 degrees). Since issue 26 such views are held back by the view
# check and either repaired by registration or kept out of training (docs/POSES.md "Every view
# earns its place"), so the aim is over the views trained on at the end, with at most 3 of the 35
# kept out. The 0.2 degree limit is 4x the good figures, so a regression in the SfM initialisation,
# the point alignment or pose refinement shows too.
ok = given["rotation_mean_deg"] > 10 and trained_mean < 0.2 and trained_trans < 0.005 and len(still) <= 3
sys.exit(0 if ok else 1)
PY
