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
# Margins from measured spreads: 27 runs (2 cores, a build and other tests alongside, 20 of them in
# a row by scripts/repeat-e2e.sh); COLMAP's features and matches differ from run to run whatever
# the seed and thread count (capture/src/colmap_sfm.cpp). The absolute rotation error is a nearly
# constant offset of the whole path (mean ~ median ~ max while consecutive frames agree to about
# 0.1 degree), 0.99-1.75 degrees, mean 1.23, sd 0.15; the 20 runs in a row had the limit at 2. Centres:
# 0.62-0.85 % of the radius. The 2.5 degree limit is 0.75 above the highest seen (8 sd above the
# mean), 2 % over twice the highest; a reconstruction that loses track, misplaces frames or gets
# the focal length wrong is several degrees and percent off.
"$hbgs" compare-poses "$work/path/true_poses" "$work/ds" --json "$work/poses.json" --max-rot-deg 2.5 \
  --max-centre-frac 0.02
# Consecutive frames relative to each other (independent of the Sim(3) fit, so the sharper check of
# the reconstruction itself): measured mean 0.089-0.137 degrees (27 runs); jitter or a wrongly
# registered frame in the path raises it past 0.3.
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
# Measured 24.31-25.79 dB (27 runs, sd 0.34). 22 dB is 2.3 dB under the lowest: a training or ingest
# regression (blurred or misregistered frames, a broken densification) costs more than that.
sys.exit(0 if psnr > 22.0 else 1)
PY
