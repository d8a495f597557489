#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Quality against model bytes in one command: trains the hybrid model over a grid of model budgets
# (anchor budget x offsets per anchor x feature width) on the real scenes in ../shared/data and on
# the built-in scene, stores each as the float model and, when `hbgs compact` exists, as the compact
# file, evaluates both on the test views, and writes out/budget_sweep/{sweep.csv,sweep.svg}.
#   scripts/budget-sweep.sh [OUT]          (default out/budget_sweep; finished runs are reused)
# Environment: HBGS_SWEEP_SCENES (default "snowmiku_plush fox sceaux_castle synth"), HBGS_SWEEP_ANCHORS
# (default "2000 8000 50000"), HBGS_SWEEP_OFFSETS ("5 10"), HBGS_SWEEP_FEATURES ("16 32"),
# HBGS_SWEEP_ITERATIONS (1000), HBGS_SWEEP_THREADS (2), GS_JOBS (build jobs, 2).
# Time: about 40 s per run at 1,000 iterations on 2 cores, so the default 48 runs take ~35 minutes.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

out=${1:-out/budget_sweep}
scenes=${HBGS_SWEEP_SCENES:-snowmiku_plush fox sceaux_castle synth}
anchors=${HBGS_SWEEP_ANCHORS:-2000 8000 50000}
offsets=${HBGS_SWEEP_OFFSETS:-5 10}
features=${HBGS_SWEEP_FEATURES:-16 32}
iterations=${HBGS_SWEEP_ITERATIONS:-1000}
threads=${HBGS_SWEEP_THREADS:-2}

cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=build/release/bin/hbgs
mkdir -p "$out"
have_compact=0
if "$hbgs" compact --help >/dev/null 2>&1; then have_compact=1; fi

source scripts/scene-dataset.sh

# One CSV row from an evaluation's results.json (its last method) and a file size.
row() {  # scene anchors offsets features format bytes results.json train_seconds
  python3 - "$@" <<'EOF'
import json, sys
scene, anchors, k, f, fmt, nbytes, results, seconds = sys.argv[1:9]
r = json.load(open(results))
m = r[sorted(r, key=lambda s: int(s.split("_")[-1]) if s.split("_")[-1].isdigit() else 0)[-1]]
print(",".join(str(x) for x in [scene, anchors, k, f, fmt, nbytes, m.get("anchors", ""), "%.4f" % m["PSNR"],
                                 "%.4f" % m["SSIM"], "%.4f" % m["LPIPS"] if "LPIPS" in m else "", seconds]))
EOF
}

csv=$out/sweep.csv
echo "scene,max_anchors,offsets,feature_dim,format,bytes,anchors,psnr,ssim,lpips,train_seconds" > "$csv.tmp"
for scene in $scenes; do
  dataset=$(scene_dataset "$scene" "$out/synth_scene")
  if [[ ! -d "$dataset" ]]; then
    echo "budget-sweep.sh: skipped $scene: $dataset not found (../shared is absent)" >&2
    continue
  fi
  for a in $anchors; do for k in $offsets; do for f in $features; do
    run=$out/$scene/a${a}_k${k}_f${f}
    if [[ ! -f "$run/results.json" ]] || ! grep -q "\"ours_$iterations\"" "$run/results.json"; then
      echo "budget-sweep.sh: training $scene, max anchors $a, $k offsets, feature width $f ($iterations iterations)" >&2
      "$hbgs" train "$dataset" --out "$run" --iterations "$iterations" --max-anchors "$a" --offsets "$k" \
        --feature-dim "$f" --threads "$threads" --save-at "$iterations" --eval-every 0 --force --quiet
    fi
    seconds=$(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); print('%.1f' % r['ours_$iterations']['train_seconds'])" "$run/results.json")
    row "$scene" "$a" "$k" "$f" float "$(stat -c %s "$run/model.hbgs")" "$run/results.json" "$seconds" >> "$csv.tmp"
    if ((have_compact)); then
      if [[ ! -f "$run/eval_compact/results.json" || "$run/model.hbgc" -ot "$run/model.hbgs" ]]; then
        "$hbgs" compact "$run" --out "$run/model.hbgc" >/dev/null
        "$hbgs" eval "$run/model.hbgc" --dataset "$dataset" --out "$run/eval_compact" >/dev/null
      fi
      row "$scene" "$a" "$k" "$f" compact "$(stat -c %s "$run/model.hbgc")" "$run/eval_compact/results.json" "$seconds" >> "$csv.tmp"
    fi
  done; done; done
done
mv "$csv.tmp" "$csv"
((have_compact)) || echo "budget-sweep.sh: this build has no 'hbgs compact'; only float models were measured" >&2

# The plot: test PSNR against bytes (log scale), one colour per scene, filled = compact, hollow = float.
python3 - "$csv" "$out/sweep.svg" <<'EOF'
import csv, math, sys
rows = list(csv.DictReader(open(sys.argv[1])))
W, H, L, R, T, B = 760, 480, 70, 170, 30, 50
if not rows:
    sys.exit("budget-sweep.sh: no rows to plot")
xs = [math.log10(float(r["bytes"])) for r in rows]
ys = [float(r["psnr"]) for r in rows]
x0, x1 = math.floor(min(xs) * 2) / 2, math.ceil(max(xs) * 2) / 2
y0, y1 = math.floor(min(ys)) - 0.5, math.ceil(max(ys)) + 0.5
if x1 <= x0: x1 = x0 + 0.5
px = lambda x: L + (x - x0) / (x1 - x0) * (W - L - R)
py = lambda y: H - B - (y - y0) / (y1 - y0) * (H - T - B)
colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"]
scenes = list(dict.fromkeys(r["scene"] for r in rows))
svg = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="sans-serif" font-size="12">' % (W, H),
       '<rect width="100%" height="100%" fill="white"/>',
       '<text x="%d" y="18" font-size="14">Test PSNR against model file size</text>' % L]
e = x0
while e <= x1 + 1e-9:
    X = px(e)
    label = "%.0f kB" % (10 ** e / 1e3) if 10 ** e < 1e6 else "%.1f MB" % (10 ** e / 1e6)
    svg.append('<line x1="%.1f" y1="%d" x2="%.1f" y2="%d" stroke="#ddd"/>' % (X, T, X, H - B))
    svg.append('<text x="%.1f" y="%d" text-anchor="middle">%s</text>' % (X, H - B + 16, label))
    e += 0.5
y = math.ceil(y0)
while y <= y1:
    Y = py(y)
    svg.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="#ddd"/>' % (L, Y, W - R, Y))
    svg.append('<text x="%d" y="%.1f" text-anchor="end">%d dB</text>' % (L - 6, Y + 4, y))
    y += 1
svg.append('<text x="%d" y="%d" text-anchor="middle">model file bytes (log scale)</text>' % ((L + W - R) // 2, H - 12))
for i, s in enumerate(scenes):
    c = colours[i % len(colours)]
    for r in rows:
        if r["scene"] != s: continue
        X, Y = px(math.log10(float(r["bytes"]))), py(float(r["psnr"]))
        fill = c if r["format"] == "compact" else "none"
        svg.append('<circle cx="%.1f" cy="%.1f" r="4" fill="%s" stroke="%s"><title>%s a%s k%s f%s %s: %s B, %s dB</title></circle>'
                   % (X, Y, fill, c, s, r["max_anchors"], r["offsets"], r["feature_dim"], r["format"], r["bytes"], r["psnr"]))
    svg.append('<circle cx="%d" cy="%d" r="4" fill="%s"/><text x="%d" y="%d">%s</text>' % (W - R + 16, T + 16 + 18 * i, c, W - R + 26, T + 20 + 18 * i, s))
n = len(scenes)
svg.append('<circle cx="%d" cy="%d" r="4" fill="none" stroke="black"/><text x="%d" y="%d">float (.hbgs)</text>' % (W - R + 16, T + 16 + 18 * n, W - R + 26, T + 20 + 18 * n))
svg.append('<circle cx="%d" cy="%d" r="4" fill="black"/><text x="%d" y="%d">compact</text>' % (W - R + 16, T + 34 + 18 * n, W - R + 26, T + 38 + 18 * n))
svg.append('</svg>')
open(sys.argv[2] + ".tmp", "w").write("\n".join(svg) + "\n")
import os; os.replace(sys.argv[2] + ".tmp", sys.argv[2])
EOF
echo "budget-sweep.sh: $(($(wc -l < "$csv") - 1)) rows in $csv, plot $out/sweep.svg"
