#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Measures how repeatable Debian's COLMAP is on one image set: runs the SfM stages hbgs runs for
# `--pose-init sfm` (CPU SIFT, exhaustive matching, mapping with the known PINHOLE intrinsics held
# fixed, permissive registration) N times on the built-in scene's images and compares the runs:
#   - features: keypoints and descriptors per image, run i against run 1;
#   - matches and two-view geometries per image pair (matching each run's own database, and, with
#     MATCH_SAME=M, matching M copies of run 1's database again: the matcher alone);
#   - poses: each run's reconstruction against the true poses after the best Sim(3)
#     (hbgs compare-poses), and run i against run 1.
# Usage: scripts/sfm-repeat.sh HBGS N THREADS [WORK_DIR]   (THREADS 1: every stage on one thread;
#        0: COLMAP's default, all cores). Prints one line per run and the seconds of each stage.
set -euo pipefail
hbgs=$1
n=${2:-3}
threads=${3:-1}
work=${4:-$(mktemp -d)}
t=$threads
[[ $t == 0 ]] && t=-1
mkdir -p "$work"
[[ -d $work/scene ]] || "$hbgs" synth --out "$work/scene" --quiet
params=$(awk '!/^#/ && NF >= 8 {print $5 "," $6 "," $7 "," $8; exit}' "$work/scene/sparse/0/cameras.txt")
run_stages() {  # $1: run folder; $2: "match-only" to re-match a copy of run 1's database
  local r=$1 db=$1/database.db t0
  mkdir -p "$r/sparse"
  if [[ ${2:-} != match-only ]]; then
    t0=$(date +%s.%N)
    colmap feature_extractor --database_path "$db" --image_path "$work/scene/images" --random_seed 0 \
      --ImageReader.single_camera 1 --ImageReader.camera_model PINHOLE --ImageReader.camera_params "$params" \
      --SiftExtraction.use_gpu 0 --SiftExtraction.num_threads "$t" --SiftExtraction.max_image_size 1600 >"$r/log" 2>&1
    echo "extract $(echo "$(date +%s.%N) - $t0" | bc)" >"$r/seconds"
  fi
  t0=$(date +%s.%N)
  colmap exhaustive_matcher --database_path "$db" --random_seed 0 --SiftMatching.use_gpu 0 \
    --SiftMatching.num_threads "$t" >>"$r/log" 2>&1
  echo "match $(echo "$(date +%s.%N) - $t0" | bc)" >>"$r/seconds"
  [[ ${2:-} == match-only ]] && return
  t0=$(date +%s.%N)
  colmap mapper --database_path "$db" --image_path "$work/scene/images" --output_path "$r/sparse" --random_seed 0 \
    --Mapper.num_threads "$t" --Mapper.abs_pose_min_num_inliers 12 --Mapper.abs_pose_min_inlier_ratio 0.1 \
    --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0 >>"$r/log" 2>&1
  echo "map $(echo "$(date +%s.%N) - $t0" | bc)" >>"$r/seconds"
}
db_diff() {  # features/matches/geometries of database $2 against $1
  python3 - "$1" "$2" <<'PY'
import sqlite3, sys
def rows(path, table, key):
    c = sqlite3.connect(path)
    return {r[0]: r[1:] for r in c.execute(f"select {key}, * from {table}")}
a, b = sys.argv[1], sys.argv[2]
out = []
for table, key in (("keypoints", "image_id"), ("descriptors", "image_id"), ("matches", "pair_id"), ("two_view_geometries", "pair_id")):
    ra, rb = rows(a, table, key), rows(b, table, key)
    keys = set(ra) | set(rb)
    differ = sum(1 for k in keys if ra.get(k) != rb.get(k))
    extra = ""
    if table == "two_view_geometries":
        inl = lambda r, k: r[k][1] if k in r else 0
        verified_a = sum(1 for k in ra if ra[k][1] > 0)
        verified_b = sum(1 for k in rb if rb[k][1] > 0)
        dif_inl = sum(abs(inl(ra, k) - inl(rb, k)) for k in keys)
        cfg = sum(1 for k in keys if (ra.get(k) or (0,0,0,0,-1))[4] != (rb.get(k) or (0,0,0,0,-1))[4])
        extra = f" (verified pairs {verified_a}/{verified_b}, config differs {cfg}, |inlier count diff| summed {dif_inl})"
    out.append(f"{table} differ {differ}/{len(keys)}{extra}")
print("; ".join(out))
PY
}
largest_model() {  # $1: run folder, $2: its sparse folder's name (default sparse)
  local best="" bestn=0
  for m in "$1"/${2:-sparse}/*/; do
    [[ -f $m/images.bin ]] || continue
    local k
    k=$(python3 -c "import struct,sys; print(struct.unpack('<Q', open(sys.argv[1],'rb').read(8))[0])" "$m/images.bin")
    if ((k > bestn)); then best=$m; bestn=$k; fi
  done
  echo "$best"
}
for ((i = 1; i <= n; ++i)); do
  r=$work/run$i
  rm -rf "$r"
  run_stages "$r"
  m=$(largest_model "$r")
  truth=$("$hbgs" compare-poses "$work/scene" "$m" 2>&1 | grep -E "registered|rotation error|matched" | tr -s ' ' | tr '\n' ' ' || true)
  line="run $i: $(tr '\n' ' ' <"$r/seconds")| vs truth: $truth"
  if ((i > 1)); then
    line+="| db vs run 1: $(db_diff "$work/run1/database.db" "$r/database.db")"
    m1=$(largest_model "$work/run1")
    line+=" | poses vs run 1: $("$hbgs" compare-poses "$m1" "$m" 2>&1 | grep -E "rotation error" | tr -s ' ' | tr '\n' ' ' || true)"
  fi
  # MAP_SEEDS="1 2": the mapper again on this run's database with other seeds; per view, how far
  # each such reconstruction is from this run's (after the Sim(3)) beside this run's error against
  # the truth, for views off by more than OFF_DEG (default 3) either way.
  for seed in ${MAP_SEEDS:-}; do
    mkdir -p "$r/sparse_seed$seed"
    colmap mapper --database_path "$r/database.db" --image_path "$work/scene/images" --output_path "$r/sparse_seed$seed" \
      --random_seed "$seed" --Mapper.num_threads "$t" --Mapper.abs_pose_min_num_inliers 12 --Mapper.abs_pose_min_inlier_ratio 0.1 \
      --Mapper.ba_refine_focal_length 0 --Mapper.ba_refine_principal_point 0 --Mapper.ba_refine_extra_params 0 >>"$r/log" 2>&1
    ms=$(largest_model "$r" sparse_seed$seed)
    "$hbgs" compare-poses "$work/scene" "$m" --json "$r/truth.json" >/dev/null 2>&1 || true
    "$hbgs" compare-poses "$work/scene" "$ms" --json "$r/truth_seed$seed.json" >/dev/null 2>&1 || true
    "$hbgs" compare-poses "$m" "$ms" --json "$r/agree_seed$seed.json" >/dev/null 2>&1 || true
    line+=" | seed $seed: $(python3 - "$r/truth.json" "$r/truth_seed$seed.json" "$r/agree_seed$seed.json" "${OFF_DEG:-3}" <<'PY'
import json, sys
def per(p):
    try: return {x["name"]: x["rotation_deg"] for x in json.load(open(p))["per_image"]}
    except Exception: return {}
t, ts, a = per(sys.argv[1]), per(sys.argv[2]), per(sys.argv[3])
off = float(sys.argv[4])
bad = sorted(n for n in t if t[n] > off)
flag = sorted(n for n in a if a[n] > off)
print(f"views off truth > {off:g} deg: this run {len(bad)}, seed run {sum(1 for n in ts if ts[n] > off)}; "
      f"disagreeing > {off:g} deg: {len(flag)} (caught {len(set(bad) & set(flag))}/{len(bad)}, false {len(set(flag) - set(bad))}); "
      f"max disagreement {max(a.values(), default=float('nan')):.2f} deg; "
      f"registered {len(t)}/{len(ts)}; missing in seed run {sorted(set(t) - set(ts))}")
PY
)"
  done
  echo "$line"
done
# The matcher alone: MATCH_SAME copies of run 1's database with its matches removed, matched again
# (with COLMAP_PRELOAD=lib.so under LD_PRELOAD, for diagnosis) and compared with the first copy.
for ((i = 1; i <= ${MATCH_SAME:-0}; ++i)); do
  r=$work/rematch$i
  rm -rf "$r"
  mkdir -p "$r"
  python3 - "$work/run1/database.db" "$r/database.db" <<'PY'
import sqlite3, sys
src = sqlite3.connect(sys.argv[1]); dst = sqlite3.connect(sys.argv[2])
src.backup(dst); dst.execute("delete from matches"); dst.execute("delete from two_view_geometries"); dst.commit()
PY
  LD_PRELOAD=${COLMAP_PRELOAD:-} run_stages "$r" match-only
  line="re-match $i of run 1's features: $(tr '\n' ' ' <"$r/seconds")"
  ((i > 1)) && line+="| vs re-match 1: $(db_diff "$work/rematch1/database.db" "$r/database.db")"
  echo "$line"
done
echo "work dir: $work"
