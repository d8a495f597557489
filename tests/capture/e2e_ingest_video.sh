#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# End to end on a real codec: render a hand-held style camera path through the built-in scene,
# encode it with the ffmpeg command (H.264, yuv420p), ingest it with `hbgs ingest` (frame selection
# + real COLMAP), check the recovered poses against the true path after a Sim(3) fit, and train on
# the dataset. Needs the `ffmpeg` and `colmap` commands; without them it says so and is skipped
# (exit 77). Usage: e2e_ingest_video.sh HBGS WORK_DIR
set -euo pipefail
hbgs=$1
work=$2
for p in ffmpeg colmap; do
  if ! command -v "$p" >/dev/null; then
    echo "SKIP: the '$p' command is not installed (scripts/install-deps.sh installs it)"
    exit 77
  fi
done
rm -rf "$work"
mkdir -p "$work"

"$hbgs" synth --path-frames 48 --path-sweep 90 --out "$work/path" --width 320 --height 240
ffmpeg -v error -nostdin -framerate 12 -i "$work/path/frames/frame_%06d.png" -c:v libx264 -pix_fmt yuv420p \
  -crf 18 "$work/clip.mp4"
"$hbgs" ingest "$work/clip.mp4" --out "$work/ds" --frames 24 --threads 2
# A second ingest into the same folder must be refused, and leave the dataset alone.
if "$hbgs" ingest "$work/clip.mp4" --out "$work/ds" --frames 24 2>"$work/refused.txt"; then
  echo "FAIL: ingest overwrote an existing dataset without --force"
  exit 1
fi
grep -q "already holds a dataset" "$work/refused.txt"
"$hbgs" compare-poses "$work/path/true_poses" "$work/ds" --json "$work/poses.json" --max-rot-deg 2 \
  --max-centre-frac 0.02
"$hbgs" train "$work/ds" --out "$work/run" --iterations 300 --quiet
python3 - "$work/run/results.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
psnr = next(iter(r.values()))["PSNR"]  # one entry per method, e.g. "ours_300"
print(f"test PSNR after 300 iterations on the ingested dataset: {psnr:.2f} dB")
sys.exit(0 if psnr > 18.0 else 1)
PY
