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
mkdir -p "$out"/{colmap_text,colmap_binary,ply,splat,spz,compressed_ply,image,model,compact,checkpoint,video,transforms,point_ply}

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

# transforms.json: the object capture's training file, a nerfstudio-style and a NeRF-synthetic-style
# file, and two broken ones (a bad frame, a syntax error).
"$hbgs" synth --object --out "$tmp/object" --width 24 --height 24 --views 3 --points 20 --quiet >/dev/null
cp "$tmp/object/transforms_train.json" "$out/transforms/synth_object_train.json"
cat >"$out/transforms/nerfstudio.json" <<'JSON'
{"camera_model": "OPENCV", "fl_x": 20, "fl_y": 21, "cx": 8, "cy": 6, "w": 16, "h": 12, "k1": 0.01, "k2": 0, "p1": 0, "p2": 0,
 "applied_transform": [[0, 1, 0, 0], [1, 0, 0, 0], [0, 0, -1, 0]], "ply_file_path": "sparse_pc.ply",
 "train_filenames": ["images/f0.png"], "val_filenames": [], "test_filenames": ["images/f1.png"],
 "frames": [{"file_path": "images/f0.png", "mask_path": "masks/f0.png", "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
            {"file_path": "images/f1.png", "fl_x": 30, "w": 16, "transform_matrix": [[0, -1, 0, 1], [1, 0, 0, 2], [0, 0, 1, 3]]}]}
JSON
printf '{"camera_angle_x": 0.6911112070083618, "frames": [{"file_path": "./train/r_0", "rotation": 0.012566370614359171, "transform_matrix": [[-0.9999, 0.0042, -0.0134, -0.0538], [-0.0140, -0.2997, 0.9539, 3.8454], [0, 0.9540, 0.2997, 1.2081], [0, 0, 0, 1]]}]}\n' >"$out/transforms/nerf_synthetic.json"
printf '{"frames": [{"file_path": "../escape", "transform_matrix": [[2, 0, 0, 0], [0, 2, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]}]}\n' >"$out/transforms/bad_frame.json"
printf '{"frames": [\n  {"file_path": "a",, }]}\n' >"$out/transforms/syntax_error.json"

# Point-cloud PLY: nerfstudio's ascii layout, and binary doubles with an extra property and faces.
printf 'ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty uint8 red\nproperty uint8 green\nproperty uint8 blue\nend_header\n0.1 0.2 0.3 255 0 7\n-1 -2 -3 1 2 3\n' >"$out/point_ply/ascii_rgb.ply"
python3 - "$out/point_ply/binary_double.ply" <<'PY'
import struct, sys
head = ("ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\n"
        "property float nx\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n")
with open(sys.argv[1], "wb") as f:
    f.write(head.encode())
    for i in range(2):
        f.write(struct.pack("<dddfBBB", 1.5 + i, -2.0, 3.0, 0.5, 10, 20, 30))
    f.write(bytes([3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]))
PY

# Images: PNG from synth, the same as JPEG (FFmpeg), and a 2x2 grey PNG.
cp "$tmp/scene/images/0000.png" "$out/image/view.png"
ffmpeg -v error -nostdin -i "$tmp/scene/images/0001.png" -q:v 5 "$out/image/view.jpg"
ffmpeg -v error -nostdin -f lavfi -i color=c=gray:s=2x2 -frames:v 1 -pix_fmt gray "$out/image/grey.png"

# Model and checkpoint: a first byte 1 asks the harness to keep the checksum matching.
{ printf '\x01'; cat "$tmp/run/model.hbgs"; } >"$out/model/tiny.hbgs"
{ printf '\x01'; cat "$tmp/run/checkpoint.bin"; } >"$out/checkpoint/tiny.ckpt"
"$hbgs" compact "$tmp/run" --out "$tmp/run/model.hbgc" --no-eval --threads 1 >/dev/null
{ printf '\x01'; cat "$tmp/run/model.hbgc"; } >"$out/compact/tiny.hbgc"
# compact/tiny_v1.hbgc, tiny_v2.hbgc and tiny_v3.hbgc (kept, not remade): the same kind of file in
# format versions 1, 2 and 3 (version 3: with a scene frame other than the identity), which the
# reader still reads (tests/model/test_compact_model.cpp reads them too).

# Video: 5 frames of 32x24 as H.264/MP4 and MJPEG/AVI.
ffmpeg -v error -nostdin -f lavfi -i testsrc=size=32x24:rate=5 -frames:v 5 -c:v libx264 -pix_fmt yuv420p "$out/video/tiny.mp4"
ffmpeg -v error -nostdin -f lavfi -i testsrc=size=32x24:rate=5 -frames:v 5 -c:v mjpeg "$out/video/tiny.avi"

du -sh "$out"
for d in "$out"/*; do echo "$(basename "$d"): $(ls "$d" | wc -l) files, $(du -sk "$d" | cut -f1) KiB"; done
