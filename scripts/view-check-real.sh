#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# What the view check (docs/POSES.md "Every view earns its place") does on the shared real scenes at
# COLMAP's own poses, where every view should earn its place: default training with it and with
# --no-view-check, test PSNR and which views were held back, repaired or kept out.
#   scripts/view-check-real.sh [ITERATIONS (3000)] [OUT (out/view-check)] [scene...]
# (VIEW_CHECK_MODES="check" runs only the runs with the check.)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
iterations=${1:-3000}
out=${2:-out/view-check}
shift 2 || true
scenes=("$@")
((${#scenes[@]})) || scenes=(snowmiku_plush sceaux_castle fox)
hbgs=${HBGS:-build/release/bin/hbgs}
mkdir -p "$out"
printf "%-16s %-14s %10s %8s  %s\n" scene mode "PSNR" "train" "views held back"
for s in "${scenes[@]}"; do
  data=../shared/data/$s
  [[ -d $data ]] || { echo "view-check-real: $data not found" >&2; exit 1; }
  for mode in ${VIEW_CHECK_MODES:-check no-check}; do
    run=$out/${s}_$mode
    extra=()
    [[ $mode == no-check ]] && extra=(--no-view-check)
    "$hbgs" train "$data" --out "$run" --iterations "$iterations" --eval-every 0 --threads 2 --force --quiet "${extra[@]}" \
      >"$run.log" 2>&1
    python3 - "$run/results.json" "$s" "$mode" "$iterations" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))["ours_" + sys.argv[4]]  # one entry per --save-at snapshot and the end
h = r["poses"]["held_back"]
print(f"{sys.argv[2]:16s} {sys.argv[3]:14s} {r['PSNR']:10.3f} {r['train_seconds']:6.0f} s  "
      f"{len(h['contradicted_by_points'])} suspect; repaired {', '.join(h['repaired']) or '-'}; confirmed "
      f"{', '.join(h['confirmed_at_given_pose']) or '-'}; kept out {', '.join(h['still_held']) or '-'}")
PY
  done
done
