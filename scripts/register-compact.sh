#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The on-device registration protocol of issue 25 (docs/POSES.md "From the compact files"): each
# trained run is written as a compact file (hbgs compact), then every test view of its dataset is
# registered from it with hbgs-device in fixed point at 1/4 resolution from 10-degree / 10 % starts,
# seeds 0, 1 and 2, with and without relocalisation from the training views (--relocalize).
#   scripts/register-compact.sh OUT RUN_FOLDER...
#     (e.g. the demo's run, and fox / snowmiku_plush trained with hbgs train --iterations 7000)
#   HBGS_RELOCALIZE: the --relocalize values to compare (default "0 3"); HBGS_SEEDS (default "0 1 2").
# Writes OUT/<run>/{model.hbgc, reloc<N>_seed<S>/register.json} and OUT/table.md: per scene and
# setting the successes per seed (< 1 degree and < 1 % of the scene radius), the views whose verdict
# is right (converged exactly when successful), the relocalised views and the median ms per view.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
if [[ $# -lt 2 ]]; then
  echo "usage: scripts/register-compact.sh OUT RUN_FOLDER..." >&2
  exit 2
fi
out=$1
shift
cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs hbgs-device
bin=build/release/bin
mkdir -p "$out"
table="$out/table.md"
{
  echo "On-device registration: compact file, fixed point, test views, 1/4 resolution, 10 deg / 10 % starts, 2 threads ($(date -u +%F), $(git rev-parse --short HEAD), load $(cut -d' ' -f1 /proc/loadavg))"
  echo
  echo "| scene (views) | --relocalize | success per seed | success | verdict right | relocalised | median ms per view | compact bytes |"
  echo "|---|---|---|---|---|---|---|---|"
} > "$table"
for run in "$@"; do
  name=$(basename "$(cd "$run/.." && pwd)")_$(basename "$run")
  [[ $(basename "$run") == run ]] || name=$(basename "$run")
  mkdir -p "$out/$name"
  hbgc="$out/$name/model.hbgc"
  [[ -s $hbgc ]] || "$bin/hbgs" compact "$run" --out "$hbgc" > "$out/$name/compact.log" 2>&1
  dataset=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["dataset"])' "$run/run.json")
  for reloc in ${HBGS_RELOCALIZE:-0 3}; do
    jsons=()
    for seed in ${HBGS_SEEDS:-0 1 2}; do
      d="$out/$name/reloc${reloc}_seed${seed}"
      rc=0
      "$bin/hbgs-device" register "$hbgc" --dataset "$dataset" --views test --downscale 4 --fixed-point --threads 2 \
        --init-noise "rot:10,trans:0.1,seed:$seed" --relocalize "$reloc" --out "$d" > "$d.log" 2>&1 || rc=$?
      if [[ $rc -ne 0 && $rc -ne 3 ]]; then cat "$d.log" >&2; exit 1; fi
      jsons+=("$d/register.json")
    done
    python3 - "$name" "$reloc" "$hbgc" "${jsons[@]}" >> "$table" <<'PY'
import json, os, statistics, sys
name, reloc, hbgc, files = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
per_seed, ok, right, reloc_n, ms, n = [], 0, 0, 0, [], 0
for f in files:
    views = json.load(open(f))["views"]
    s = sum(v["success"] for v in views)
    per_seed.append(str(s))
    ok += s
    right += sum(v["success"] == (v["verdict"] == "converged") for v in views)
    reloc_n += sum(v.get("relocalized_from") is not None for v in views)
    ms += [v["ms"] for v in views]
    n += len(views)
print(f"| {name} ({n // len(files)}) | {reloc} | {' / '.join(per_seed)} | {ok} of {n} | {right} of {n} | {reloc_n} | "
      f"{statistics.median(ms):.0f} | {os.path.getsize(hbgc)} |")
PY
  done
done
cat "$table"
