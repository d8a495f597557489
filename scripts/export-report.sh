#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Scenes that travel, measured the way issue 16 asks: on snowmiku_plush, fox and the built-in scene
# (3,000-iteration models), the model baked into a 3DGS PLY at SH degrees 0-3 (test PSNR of the PLY
# against the anchor model, 8-bit renders), the SH-3 bake converted to every format (bytes and test
# PSNR), and registration of the built-in scene's test views against the PLY and against the model
# (10 deg / 10 % starts, full and 1/4 resolution).
#   scripts/export-report.sh [OUT]      (default out/export_report; finished steps are reused)
# Models: out/on_device/<scene>/run (scripts/on-device-report.sh trains them) or trained here;
# HBGS_REPORT_RUNS="scene=RUN ..." names others. Needs ../shared/data; about 40 minutes on 2 cores
# with the models trained, most of it in the distillation of 12 bakes.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=${1:-out/export_report}
threads=${HBGS_REPORT_THREADS:-2}
cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=build/release/bin/hbgs
mkdir -p "$out"
source scripts/report-scenes.sh

rows=()
for scene in "${report_scenes[@]}"; do
  report_scene "$scene" out/on_device/synth_scene "out/on_device/$scene/run" || continue
  w=$out/$scene
  mkdir -p "$w"
  for sh in 0 1 2 3; do
    if [[ ! -f $w/sh$sh.txt ]]; then
      echo "== $scene: bake at SH degree $sh"
      "$hbgs" export "$run" --out "$w/sh$sh.ply" --sh-degree "$sh" --threads "$threads" >"$w/sh$sh.txt.tmp"
      mv "$w/sh$sh.txt.tmp" "$w/sh$sh.txt"
    fi
  done
  for fmt in spz compressed.ply splat; do
    [[ -f $w/sh3.$fmt ]] || "$hbgs" export "$w/sh3.ply" --out "$w/sh3.$fmt" --no-eval >/dev/null
    [[ -f $w/eval_$fmt/results.json ]] || "$hbgs" eval "$w/sh3.$fmt" --dataset "$dataset" --out "$w/eval_$fmt" --threads "$threads" >/dev/null
  done
  [[ -f $w/eval_model/results.json ]] || "$hbgs" eval "$run" --dataset "$dataset" --out "$w/eval_model" --threads "$threads" >/dev/null
  if [[ $scene == synth ]]; then
    for ds in 1 4; do
      for src in model ply; do
        input=$run
        [[ $src == ply ]] && input=$w/sh3.ply
        [[ -f $w/register_${src}_$ds/register.json ]] ||
          "$hbgs" register "$input" --dataset "$dataset" --views test --downscale "$ds" --init-noise rot:10,trans:0.1,seed:1 \
            --out "$w/register_${src}_$ds" --threads "$threads" --quiet >/dev/null || [[ $? -eq 3 ]]
      done
    done
  fi
  rows+=("$scene|$run|$w")
done

python3 - "$out" "${rows[@]}" <<'PY'
import json, os, re, statistics, sys
out = sys.argv[1]
lines = ["## Baked 3DGS PLY against the anchor model (test views, 8-bit renders)", "",
         "| scene | model | SH 0 | SH 1 | SH 2 | SH 3 | Gaussians | bake + distillation s (SH 3) |", "|---|---|---|---|---|---|---|---|"]
fmt_lines = ["", "## The SH-3 bake in every format", "",
             "| scene | format | bytes | bytes per splat | test PSNR |", "|---|---|---|---|---|"]
reg_lines = []
for row in sys.argv[2:]:
    scene, run, w = row.split("|")
    psnr = {}
    for sh in range(4):
        t = open(os.path.join(w, "sh%d.txt" % sh)).read()
        m = re.search(r"model ([0-9.]+) dB, exported ([0-9.]+) dB", t)
        psnr[sh] = (float(m.group(1)), float(m.group(2)))
        if sh == 3:
            n = int(re.search(r"  (\d+) Gaussians", t).group(1))
            secs = re.search(r"\(3DGS PLY, ([0-9.]+) s\)", t).group(1)
    model = psnr[3][0]
    cells = ["%.3f (%+.3f)" % (psnr[s][1], psnr[s][1] - model) for s in range(4)]
    lines.append("| %s | %.3f dB | %s | %d | %s |" % (scene, model, " | ".join(cells), n, secs))
    for fmt in ("ply", "spz", "compressed.ply", "splat"):
        path = os.path.join(w, "sh3." + fmt)
        size = os.path.getsize(path)
        if fmt == "ply":
            p = psnr[3][1]
        else:
            p = json.load(open(os.path.join(w, "eval_" + fmt, "results.json")))["ours"]["PSNR"]
        fmt_lines.append("| %s | %s | %d | %.1f | %.3f dB (%+.3f) |" % (scene, fmt, size, size / n, p, p - model))
    if scene == "synth":
        reg_lines += ["", "## Registration on the built-in scene (test views, 10 deg / 10 % starts, seed 1)", "",
                      "| resolution | against | median rotation | median translation (x radius) | within 1 deg and 1 % | converged | median s/view |",
                      "|---|---|---|---|---|---|---|"]
        for ds in (1, 4):
            for src in ("model", "ply"):
                j = json.load(open(os.path.join(w, "register_%s_%d" % (src, ds), "register.json")))
                v = j["views"]
                reg_lines.append("| 1/%d | %s | %.3f deg | %.4f | %d/%d | %d/%d | %.2f |" % (
                    ds, "anchor model" if src == "model" else "3DGS PLY (SH 3)", statistics.median(x["rotation_deg"] for x in v),
                    statistics.median(x["translation_fraction"] for x in v), sum(bool(x["success"]) for x in v), len(v),
                    sum(x["verdict"] == "converged" for x in v), len(v), statistics.median(x["ms"] for x in v) / 1000))
text = "\n".join(lines + fmt_lines + reg_lines) + "\n"
open(os.path.join(out, "report.md"), "w").write(text)
print(text)
PY
echo "written: $out/report.md"
