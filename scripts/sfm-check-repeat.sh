#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Ingests the same image set (the built-in scene's 40 views, exhaustive matching) N times with
# `hbgs ingest` and measures what the SfM consistency check (capture/colmap_sfm.h) does with
# COLMAP's unrepeatable reconstructions: per run, the views more than OFF_DEG (default 3) degrees
# from the truth after the best Sim(3) (hbgs compare-poses), the views the check flagged as suspect
# (ingest.json), hits, misses and false alarms, the check's seconds against the ingest's, and how
# far the run's poses are from run 1's (is ingesting twice the same?).
# Usage: scripts/sfm-check-repeat.sh HBGS [N=10] [WORK_DIR] [extra ingest options...]
# REUSE=1 keeps the datasets already ingested in WORK_DIR and only compares them again.
# POSE_INIT=1 runs COLMAP as `hbgs train --pose-init sfm` does (the known PINHOLE intrinsics held
# fixed, permissive registration) through a wrapper given as --colmap. TRAIN_ONLY=1 gives it only
# the 35 training views (every 8th image by name left out), as `--pose-init sfm` sees them.
set -euo pipefail
hbgs=$1
n=${2:-10}
work=${3:-$(mktemp -d)}
shift $(($# < 3 ? $# : 3))
mkdir -p "$work"
[[ -d $work/scene ]] || "$hbgs" synth --out "$work/scene" --quiet
images=$work/scene/images
if [[ ${TRAIN_ONLY:-0} == 1 ]]; then  # the training views only (every 8th by name held out), as --pose-init sfm sees them
  images=$work/train_images
  mkdir -p "$images"
  k=0
  for f in $(ls "$work/scene/images" | sort); do
    ((k % 8 == 0)) || ln -sf "$work/scene/images/$f" "$images/$f"
    k=$((k + 1))
  done
fi
# The truth under the names ingest gives the frames (frame_NNNNNN.png, NNNNNN: the image's place in
# name order).
mkdir -p "$work/truth/sparse/0"
cp "$work/scene/sparse/0/cameras.txt" "$work/truth/sparse/0/"
echo "# no points: only the poses are compared" >"$work/truth/sparse/0/points3D.txt"
python3 - "$work/scene/sparse/0/images.txt" "$work/truth/sparse/0/images.txt" "$images" <<'PY'
import os, sys
lines = [l.rstrip("\n") for l in open(sys.argv[1])]
head = [l for l in lines if l.startswith("#")]
body = [l for l in lines if not l.startswith("#")]
records = [(body[i], body[i + 1] if i + 1 < len(body) else "") for i in range(0, len(body), 2) if body[i].strip()]
order = sorted(os.listdir(sys.argv[3]))
records = [r for r in records if r[0].split()[9] in order]
with open(sys.argv[2], "w") as f:
    for l in head: f.write(l + "\n")
    for pose, points in records:
        parts = pose.split()
        parts[9] = "frame_%06d.png" % order.index(parts[9])
        f.write(" ".join(parts) + "\n" + points + "\n")
PY
extra=()
if [[ ${POSE_INIT:-0} == 1 ]]; then
  params=$(awk '!/^#/ && NF >= 8 {print $5 "," $6 "," $7 "," $8; exit}' "$work/scene/sparse/0/cameras.txt")
  {
    echo '#!/usr/bin/env bash'
    echo '# COLMAP with the pose initialiser options (scripts/sfm-check-repeat.sh POSE_INIT=1).'
    echo 'cmd=$1; shift; args=()'
    echo 'while [[ $# -gt 0 ]]; do'
    echo "  if [[ \$1 == --ImageReader.camera_model ]]; then args+=(--ImageReader.camera_model PINHOLE --ImageReader.camera_params $params); shift 2; continue; fi"
    echo '  args+=("$1"); shift'
    echo 'done'
    echo '[[ $cmd == mapper ]] && args+=(--Mapper.abs_pose_min_num_inliers 12 --Mapper.abs_pose_min_inlier_ratio 0.1 --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0)'
    echo 'exec colmap "$cmd" "${args[@]}"'
  } >"$work/colmap-pose-init"
  chmod +x "$work/colmap-pose-init"
  extra=(--colmap "$work/colmap-pose-init")
fi
for ((i = 1; i <= n; ++i)); do
  ds=$work/ds$i
  [[ ${REUSE:-0} == 1 && -f $ds/ingest.json ]] || rm -rf "$ds" "$ds.partial"
  t0=$SECONDS
  if [[ ${REUSE:-0} == 1 && -f $ds/ingest.json ]]; then
    :  # measured before: only the comparisons again
  elif ! "$hbgs" ingest "$images" --out "$ds" --matcher exhaustive --frames 40 --blur-ratio 0 "${extra[@]}" "$@" >"$work/ingest$i.log" 2>&1; then
    echo "run $i: ingest failed after $((SECONDS - t0)) s: $(tail -3 "$work/ingest$i.log" | tr '\n' ' ')"
    continue
  fi
  "$hbgs" compare-poses "$work/truth" "$ds" --json "$ds/truth.json" >"$ds/truth.txt" 2>&1 || true
  [[ $i -gt 1 && -d $work/ds1 ]] && "$hbgs" compare-poses "$work/ds1" "$ds" >"$ds/vs_run1.txt" 2>&1 || true
  python3 - "$ds/ingest.json" "$ds/truth.json" "${OFF_DEG:-3}" "$((SECONDS - t0))" "$ds/vs_run1.txt" "$i" <<'PY'
import json, os, sys
ing = json.load(open(sys.argv[1]))
truth = {x["name"]: x["rotation_deg"] for x in json.load(open(sys.argv[2]))["per_image"]}
off, seconds, run = float(sys.argv[3]), int(sys.argv[4]), sys.argv[6]
c = ing["colmap"]["consistency"]
bad = {n for n, e in truth.items() if e > off}
flagged = set(c["suspect_views"])
worst = max(truth.values(), default=0)
vs1 = ""
if os.path.exists(sys.argv[5]):
    for line in open(sys.argv[5]):
        if "rotation error" in line: vs1 = " | vs run 1:" + line.split(":", 1)[1].strip()
sec = ing["colmap"]["seconds"]
print(f"run {run}: {ing['colmap']['registered']}/{ing['colmap']['images']} registered, truth max {worst:.2f} deg, "
      f"{len(bad)} view(s) > {off:g} deg {sorted(bad)}; suspect {sorted(flagged)}: caught {len(bad & flagged)}/{len(bad)}, "
      f"false {len(flagged - bad)}; runs agree to median {c['rotation_median_deg']:.2f} max {c['rotation_max_deg']:.2f} deg; "
      f"check {c['seconds']:.1f} s of {seconds} s (features {sec['features']:.1f}, matching {sec['matching']:.1f}, "
      f"mapping {sec['mapping']:.1f}){vs1}")
for n in sorted(bad | flagged):
    v = next((v for v in c["views"] if v["name"] == n), None)
    print(f"    {n}: truth {truth.get(n, float('nan')):.2f} deg, check {v['rotation_deg'] if v else float('nan'):.2f} deg "
          f"{100 * v['centre_fraction'] if v else float('nan'):.1f} % radius, disagreeing {v['disagreeing'] if v else '-'}/{v['check_runs'] if v else '-'}")
PY
done
echo "work dir: $work"
