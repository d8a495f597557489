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
# Margins from measured spreads (6 runs, 2 cores with a build and other tests alongside; COLMAP's
# matching and mapping are not reproducible, see capture/src/colmap_sfm.cpp): the absolute rotation
# error is a nearly constant offset over the path (mean ~ median ~ max), 1.12-1.47 degrees,
# centres 0.68-0.85 % of the radius. 2 degrees is 0.5 above the highest (about 5 standard deviations
# above the mean), 2 % over twice the highest; a reconstruction that loses track, misplaces frames
# or gets the focal length wrong is several degrees and percent off.
"$hbgs" compare-poses "$work/path/true_poses" "$work/ds" --json "$work/poses.json" --max-rot-deg 2 \
  --max-centre-frac 0.02
# Consecutive frames relative to each other (independent of the Sim(3) fit): measured mean
# 0.094-0.130 degrees; jitter or a wrongly registered frame in the path raises it past 0.3.
python3 - "$work/poses.json" <<'PY'
import json, sys
rel = json.load(open(sys.argv[1]))["relative_rotation_deg"]["mean"]
print(f"relative rotation between consecutive frames: mean {rel:.4f} deg (limit 0.3)")
sys.exit(0 if rel < 0.3 else 1)
PY
# Fixed thread count (and the default seed): the same work split on every machine.
"$hbgs" train "$work/ds" --out "$work/run" --iterations 300 --threads 2 --quiet
python3 - "$work/run/results.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
psnr = next(iter(r.values()))["PSNR"]  # one entry per method, e.g. "ours_300"
print(f"test PSNR after 300 iterations on the ingested dataset: {psnr:.2f} dB (limit 22)")
# Measured 24.38-25.48 dB (6 runs). 22 dB is about 2.5 dB under the lowest: a training or ingest
# regression (blurred or misregistered frames, a broken densification) costs more than that.
sys.exit(0 if psnr > 22.0 else 1)
PY
