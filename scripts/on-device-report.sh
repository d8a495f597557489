#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The on-device mode against the float path on snowmiku_plush, fox and the built-in scene, the way
# issue 14 measures it: 3,000-iteration models, the compact file (size), test PSNR of the float
# model against the compact file rendered in fixed point (8-bit renders; mean and worst view), and
# registration of every test view from 10 deg / 10 % at 1/4 resolution, float and fixed point side
# by side (median rotation, success within 1 deg and 1 % of the radius, s/view, verdict agreement).
#   scripts/on-device-report.sh [OUT]      (default out/on_device; finished runs are reused)
# HBGS_REPORT_RUNS="scene=RUN ..." reuses trained run folders (e.g. snowmiku_plush=/path/run).
# Needs ../shared/data; about 10 minutes on 2 cores with training, 1 without.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=${1:-out/on_device}
threads=${HBGS_REPORT_THREADS:-2}
cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs hbgs-device
hbgs=build/release/bin/hbgs
dev=build/release/bin/hbgs-device
mkdir -p "$out"
source scripts/report-scenes.sh

rows=()
for scene in "${report_scenes[@]}"; do
  report_scene "$scene" "$out/synth_scene" "$out/$scene/run" || continue
  w=$out/$scene
  mkdir -p "$w"
  "$hbgs" compact "$run" --out "$w/model.hbgc" --dataset "$dataset" --no-eval --threads "$threads" >/dev/null
  "$dev" eval "$run" --dataset "$dataset" --out "$w/eval_float" --threads "$threads" >/dev/null
  "$dev" eval "$w/model.hbgc" --dataset "$dataset" --out "$w/eval_fixed" --fixed-point --threads "$threads" >/dev/null
  for mode in float fixed; do
    model=$run flag=
    if [[ $mode == fixed ]]; then model=$w/model.hbgc flag=--fixed-point; fi
    "$dev" register "$model" --dataset "$dataset" --views test --downscale 4 --init-noise rot:10,trans:0.1,seed:1 \
      --out "$w/register_$mode" --threads "$threads" --quiet $flag >/dev/null || [[ $? -eq 3 ]]
  done
  rows+=("$scene|$run|$w")
done

python3 - "$out" "${rows[@]}" <<'PY'
import json, os, statistics, sys
out = sys.argv[1]
lines = ["| scene | float file | compact file | test PSNR float | fixed point (compact) | change | worst view | "
         "registration float: median rot, success, s/view, verdict agrees | fixed point: median rot, success, s/view, verdict agrees |",
         "|---|---|---|---|---|---|---|---|---|"]
for row in sys.argv[2:]:
    scene, run, w = row.split("|")
    fb = os.path.getsize(os.path.join(run, "model.hbgs")); cb = os.path.getsize(os.path.join(w, "model.hbgc"))
    pf = json.load(open(os.path.join(w, "eval_float", "per_view.json")))["ours"]["PSNR"]
    pq = json.load(open(os.path.join(w, "eval_fixed", "per_view.json")))["ours"]["PSNR"]
    mf, mq = statistics.mean(pf.values()), statistics.mean(pq.values())
    worst = min(pf, key=lambda k: pq[k] - pf[k])
    reg = []
    for mode in ("float", "fixed"):
        j = json.load(open(os.path.join(w, "register_" + mode, "register.json")))
        v = j["views"]
        agree = sum((x["verdict"] == "converged") == bool(x["success"]) for x in v)
        reg.append("%.3f deg, %d/%d, %.3f s, %d/%d" % (statistics.median(x["rotation_deg"] for x in v),
                   sum(bool(x["success"]) for x in v), len(v), statistics.median(x["ms"] for x in v) / 1000, agree, len(v)))
    lines.append("| %s | %.3f MB | %.3f MB | %.3f dB | %.3f dB | %+.3f dB | %s %+.3f dB | %s | %s |" % (
        scene, fb / 1e6, cb / 1e6, mf, mq, mq - mf, worst, pq[worst] - pf[worst], reg[0], reg[1]))
text = "\n".join(lines) + "\n"
open(os.path.join(out, "report.md"), "w").write(text)
print(text)
PY
echo "written: $out/report.md"
