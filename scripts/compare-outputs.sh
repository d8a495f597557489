#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Are two builds' outputs identical? Runs the same short job on the built-in scene with two hbgs
# programs (for example the commit before a refactor, built beside this one, and this one) and
# compares what a user gets: the generated scene's files, every iteration's training loss, the
# evaluation figures, the test renders and the render command's figures. Exits 1 on any difference.
#   scripts/compare-outputs.sh OLD_HBGS NEW_HBGS [WORKDIR] [ITERATIONS]
# Example (the baseline built in a worktree beside this clone):
#   git worktree add ../baseline <commit> && (cd ../baseline && cmake --preset release && cmake --build --preset release)
#   scripts/compare-outputs.sh ../baseline/build/release/bin/hbgs build/release/bin/hbgs
set -euo pipefail

old=${1:?usage: compare-outputs.sh OLD_HBGS NEW_HBGS [WORKDIR] [ITERATIONS]}
new=${2:?usage: compare-outputs.sh OLD_HBGS NEW_HBGS [WORKDIR] [ITERATIONS]}
work=${3:-$(mktemp -d)}
iterations=${4:-300}
mkdir -p "$work"
echo "compare-outputs: $old vs $new, $iterations iterations, in $work"

for side in old new; do
  bin=${!side}
  rm -rf "$work/$side"
  mkdir -p "$work/$side"
  "$bin" synth --out "$work/$side/scene" > "$work/$side/synth.log" 2>&1
  "$bin" train "$work/$side/scene" --out "$work/$side/run" --iterations "$iterations" --eval-every 100 \
    --save-at "$iterations" > "$work/$side/train.log" 2>&1
  "$bin" eval "$work/$side/run" --out "$work/$side/eval" --split all > "$work/$side/eval.log" 2>&1
  "$bin" render "$work/$side/run" --out "$work/$side/render" > "$work/$side/render.log" 2>&1
done

python3 - "$work" <<'EOF'
import hashlib, json, os, sys
work = sys.argv[1]
problems = []

def digest(path):
    return hashlib.sha256(open(path, 'rb').read()).hexdigest()

def tree(root):
    return sorted(os.path.relpath(os.path.join(d, f), root) for d, _, fs in os.walk(root) for f in fs)

# The generated scene: every file byte for byte.
a, b = f"{work}/old/scene", f"{work}/new/scene"
if tree(a) != tree(b):
    problems.append("scene: the file lists differ")
else:
    for rel in tree(a):
        if digest(f"{a}/{rel}") != digest(f"{b}/{rel}"):
            problems.append(f"scene: {rel} differs")
print(f"scene: {len(tree(a))} files compared")

# Training: every iteration's loss, bit for bit (JSON keeps float32 values exactly).
la = json.load(open(f"{work}/old/run/progress.json"))["losses"]
lb = json.load(open(f"{work}/new/run/progress.json"))["losses"]
first = next((i for i, (x, y) in enumerate(zip(la, lb)) if x != y), None)
if len(la) != len(lb) or first is not None:
    problems.append(f"training losses differ (lengths {len(la)}/{len(lb)}, first at iteration {first})")
print(f"training losses: {len(la)} iterations compared, last {la[-1]!r} vs {lb[-1]!r}")

# Figures that must not change: times may, and paths name each side's own folder.
def strip(x, side):
    if isinstance(x, dict):
        return {k: strip(v, side) for k, v in x.items()
                if not (k.endswith("_ms") or k.endswith("ms_median") or k == "ms" or "seconds" in k
                        or k.startswith("stage_ms"))}
    if isinstance(x, list):
        return [strip(v, side) for v in x]
    if isinstance(x, str):
        return x.replace(f"{work}/{side}/", f"{work}/SIDE/")
    return x
for rel in ["run/results.json", "run/per_view.json", "eval/results.json", "eval/per_view.json"]:
    ja, jb = strip(json.load(open(f"{work}/old/{rel}")), "old"), strip(json.load(open(f"{work}/new/{rel}")), "new")
    if ja != jb:
        problems.append(f"{rel}: figures differ")
    print(f"{rel}: compared")
ra = strip(json.load(open(f"{work}/old/render/render.json")), "old")
rb = strip(json.load(open(f"{work}/new/render/render.json")), "new")
if ra != rb:
    problems.append("render/render.json: figures differ")
# Images: the test renders of the run and the render command's PNGs, byte for byte.
for sub in ["run/test", "render"]:
    pa, pb = f"{work}/old/{sub}", f"{work}/new/{sub}"
    pngs = [r for r in tree(pa) if r.endswith(".png")]
    if pngs != [r for r in tree(pb) if r.endswith(".png")]:
        problems.append(f"{sub}: the PNG lists differ")
        continue
    diff = [r for r in pngs if digest(f"{pa}/{r}") != digest(f"{pb}/{r}")]
    if diff:
        problems.append(f"{sub}: {len(diff)} of {len(pngs)} PNGs differ, e.g. {diff[0]}")
    print(f"{sub}: {len(pngs)} PNGs compared")
with open(f"{work}/new/run/results.json") as f:
    r = json.load(f)
    for method, m in r.items():
        if isinstance(m, dict) and "PSNR" in m:
            print(f"results {method}: PSNR {m['PSNR']}, SSIM {m.get('SSIM')}, LPIPS {m.get('LPIPS')}")
if problems:
    print("compare-outputs: DIFFERENT\n  " + "\n  ".join(problems))
    sys.exit(1)
print("compare-outputs: identical")
EOF
