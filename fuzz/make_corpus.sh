#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Makes the fuzzers' seed corpora in fuzz/corpus/<harness>/ from files hbgs (and COLMAP, FFmpeg)
# write, plus a few hand-made edge cases. Needs a built hbgs with synth (Embree), colmap, ffmpeg and
# python3. The corpora are committed; rerun this after a file format changes.
#   fuzz/make_corpus.sh [path to hbgs, default build/release/bin/hbgs]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
hbgs=$(realpath "${1:-../build/release/bin/hbgs}")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
out=corpus
rm -rf "$out"
mkdir -p "$out"/{colmap_text,colmap_binary,ply,splat,spz,compressed_ply,image,model,compact,checkpoint,video}

# A tiny scene: 3 views of 40x32 (LPIPS needs 31 px a side) (view 0 is the test view, so 2 train views, as the checkpoint
# harness's trainer has) and 30 points; a 2-iteration run with the harness's budgets.
"$hbgs" synth --out "$tmp/scene" --width 40 --height 32 --views-arc 1 --views-orbit 2 --points 30 --quiet
"$hbgs" train "$tmp/scene" --out "$tmp/run" --iterations 2 --max-anchors 64 --max-gaussians 640 --eval-every 0 --threads 1 --quiet

# COLMAP text and binary: the first byte picks the file (0 cameras, 1 images, 2 points3D).
colmap model_converter --input_path "$tmp/scene/sparse/0" --output_path "$tmp" --output_type BIN >/dev/null
i=0
for f in cameras images points3D; do
  { printf "\\x$(printf %02x $i)"; cat "$tmp/scene/sparse/0/$f.txt"; } >"$out/colmap_text/$f.txt"
  { printf "\\x$(printf %02x $i)"; cat "$tmp/$f.bin"; } >"$out/colmap_binary/$f.bin"
  i=$((i + 1))
done
printf '\x00# comment only\n' >"$out/colmap_text/comment.txt"
printf '\x011 1 0 0 0 0 0 0 1 ../escape.png\n\n' >"$out/colmap_text/escape_name.txt"
printf '\x001 SIMPLE_RADIAL 32 24 30 16 12 0.1\n2 OPENCV 32 24 30 30 16 12 0 0 0 0\n' >"$out/colmap_text/camera_models.txt"

# 3DGS PLY: two Gaussians at SH degree 0 and one at degree 1 (written here, the layout is public).
python3 - "$out/ply" <<'PY'
import struct, sys
base = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
def ply(path, n, rest):
    props = base + [f"f_rest_{j}" for j in range(rest)]
    head = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % n + "".join(f"property float {p}\n" for p in props) + "end_header\n"
    with open(path, "wb") as f:
        f.write(head.encode())
        for i in range(n):
            f.write(struct.pack("<%df" % len(props), *[0.1 * (i + k) for k in range(len(props))]))
ply(sys.argv[1] + "/sh0.ply", 2, 0)
ply(sys.argv[1] + "/sh1.ply", 1, 9)
PY

# .splat, .spz and compressed.ply: tiny files of each layout (fuzz/make_splat_corpus.py).
python3 make_splat_corpus.py "$out"

# Images: PNG from synth, the same as JPEG (FFmpeg), and a 2x2 grey PNG.
cp "$tmp/scene/images/0000.png" "$out/image/view.png"
ffmpeg -v error -nostdin -i "$tmp/scene/images/0001.png" -q:v 5 "$out/image/view.jpg"
ffmpeg -v error -nostdin -f lavfi -i color=c=gray:s=2x2 -frames:v 1 -pix_fmt gray "$out/image/grey.png"

# Model and checkpoint: a first byte 1 asks the harness to keep the checksum matching.
{ printf '\x01'; cat "$tmp/run/model.hbgs"; } >"$out/model/tiny.hbgs"
{ printf '\x01'; cat "$tmp/run/checkpoint.bin"; } >"$out/checkpoint/tiny.ckpt"
"$hbgs" compact "$tmp/run" --out "$tmp/run/model.hbgc" --no-eval --threads 1 >/dev/null
{ printf '\x01'; cat "$tmp/run/model.hbgc"; } >"$out/compact/tiny.hbgc"

# Video: 5 frames of 32x24 as H.264/MP4 and MJPEG/AVI.
ffmpeg -v error -nostdin -f lavfi -i testsrc=size=32x24:rate=5 -frames:v 5 -c:v libx264 -pix_fmt yuv420p "$out/video/tiny.mp4"
ffmpeg -v error -nostdin -f lavfi -i testsrc=size=32x24:rate=5 -frames:v 5 -c:v mjpeg "$out/video/tiny.avi"

du -sh "$out"
for d in "$out"/*; do echo "$(basename "$d"): $(ls "$d" | wc -l) files, $(du -sk "$d" | cut -f1) KiB"; done
