#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Object captures end to end at a reduced size (issue 15): the built-in object scene (RGBA images,
# transparent background) trained on white, and its cluttered variant (the object among clutter,
# masks marking it) trained on white through the masks; both evaluated as rendered against the
# photos composited on white. The full-size figures (200x200, 48 views, 3,000 iterations, 30 dB)
# are in docs/MODEL.md and the issue notes; this run checks that the mechanisms hold together.
# Usage: e2e_object_train.sh HBGS WORK_DIR
set -euo pipefail
hbgs=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
"$hbgs" synth --object --out "$work/transparent" --width 96 --height 96 --views 24 --quiet
"$hbgs" synth --object --object-background cluttered --out "$work/cluttered" --width 96 --height 96 --views 24 --quiet
for kind in transparent cluttered; do
  "$hbgs" train "$work/$kind" --out "$work/run_$kind" --iterations 600 --background white --eval-every 0 --threads 2 --quiet
done
python3 - "$work" <<'PY'
import json, sys
work = sys.argv[1]
ok = True
psnr = {}
for kind in ("transparent", "cluttered"):
    r = json.load(open(f"{work}/run_{kind}/results.json"))["ours_600"]
    print(f"{kind}: test PSNR {r['PSNR']:.2f} dB, inside the mask {r['PSNR_masked']:.2f} dB, alpha MAE {r['alpha_MAE']:.4f}, "
          f"alpha IoU {r['alpha_IoU']:.4f}, background {r['background']}")
    # Limits from a measured run with margin: 28.86 and 28.54 dB, alpha IoU 0.986 and 0.987 (the
    # masked clutter costs 0.3 dB). The full-size figures are 30 dB and more (docs/MODEL.md).
    ok = ok and r["background"] == "white" and r["PSNR"] > 26.0 and r["alpha_IoU"] > 0.95
    psnr[kind] = r["PSNR"]
ok = ok and psnr["cluttered"] > psnr["transparent"] - 1.5
sys.exit(0 if ok else 1)
PY
