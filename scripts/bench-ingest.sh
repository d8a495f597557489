#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Ingestion on a real hand-held video in one command: encodes the frames of
# ../shared/data/fox/images_800 (frames of a phone video, 440x786) as an H.264 clip with the ffmpeg
# command, runs `hbgs ingest` on it (frame selection + COLMAP), and compares the recovered poses with
# the dataset's own COLMAP poses after a Sim(3) fit (`hbgs compare-poses`; frame i of the clip is
# the i-th image by name). Writes out/bench_ingest/{clip.mp4, ds/, poses.json, ingest.log} and
# prints the figures. Needs ffmpeg and colmap (scripts/install-deps.sh installs both).
#   scripts/bench-ingest.sh [SCENE_DIR]   (default ../shared/data/fox; HBGS_BENCH_INGEST_ARGS adds
#   `hbgs ingest` options, e.g. "--frames 25"; GS_JOBS: build jobs, default 2)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

scene=${1:-../shared/data/fox}
images=$scene/images_800
[[ -d "$images" ]] || images=$scene/images
out=out/bench_ingest
if [[ ! -d "$images" ]]; then
  echo "bench-ingest.sh: skipped: $images not found (../shared is absent); pass a scene folder" >&2
  exit 0
fi
for p in ffmpeg colmap; do
  command -v "$p" >/dev/null || { echo "bench-ingest.sh: the '$p' command is missing (scripts/install-deps.sh)" >&2; exit 1; }
done

cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=build/release/bin/hbgs
rm -rf "$out"
mkdir -p "$out/truth"

# H.264 4:2:0 needs even sizes: crop a trailing odd row or column.
first=$(ls "$images" | head -1)
ffmpeg -v error -nostdin -framerate 10 -pattern_type glob -i "$images/*.${first##*.}" \
  -vf "crop=trunc(iw/2)*2:trunc(ih/2)*2:0:0" -c:v libx264 -pix_fmt yuv420p -crf 18 "$out/clip.mp4"
frames=$(ls "$images" | wc -l)
# shellcheck disable=SC2086
"$hbgs" ingest "$out/clip.mp4" --out "$out/ds" --frames "$frames" --threads "${GS_JOBS:-2}" \
  ${HBGS_BENCH_INGEST_ARGS:-} | tee "$out/ingest.log"

# The dataset's poses under the clip's frame names (i-th image by name = frame i).
model=$scene/sparse/0
cp "$model/cameras.txt" "$model/points3D.txt" "$out/truth/"
ls "$images" | awk '{printf "%s frame_%06d.png\n", $1, NR-1}' > "$out/names.txt"
awk 'NR==FNR { m[$1] = $2; next } { if ($0 !~ /^#/ && NF >= 10 && ($10 in m)) $10 = m[$10]; print }' \
  "$out/names.txt" "$model/images.txt" > "$out/truth/images.txt"
"$hbgs" compare-poses "$out/truth" "$out/ds" --json "$out/poses.json"
