#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Far and scaled scenes at full size: the built-in scene (256x192, 40 views) moved by 1e5 and 1e7
# units and scaled by 1e-3 and 1e3 (COLMAP text with every double's digits, the images linked),
# trained ITERATIONS iterations each on one thread, against the original; prints one table of test
# PSNR, training seconds, Gaussians and the exported PLY's mean position against where the
# original's Gaussians land after the same move. With OLD_HBGS (e.g. a build of the commit before
# scene frames) the same runs are repeated with it for the "before" column.
#   scripts/scene-frame.sh HBGS [WORKDIR] [ITERATIONS] [OLD_HBGS]
set -euo pipefail

hbgs=${1:?usage: scene-frame.sh HBGS [WORKDIR] [ITERATIONS] [OLD_HBGS]}
work=${2:-$(mktemp -d)}
iterations=${3:-1000}
old=${4:-}
mkdir -p "$work"
echo "scene-frame: $hbgs, $iterations iterations, in $work"

[ -d "$work/original/sparse" ] || "$hbgs" synth --out "$work/original" --threads 1 -q > "$work/synth.log" 2>&1

# name scale shift_x shift_y shift_z
cases="original 1 0 0 0
moved_1e5 1 100000 -100000 50000
moved_1e7 1 10000000 10000000 -10000000
scaled_1e-3 0.001 0 0 0
scaled_1e3 1000 0 0 0"

python3 - "$work" <<'EOF'
import math, os, sys
work = sys.argv[1]
cases = [("moved_1e5", 1, (1e5, -1e5, 5e4)), ("moved_1e7", 1, (1e7, 1e7, -1e7)),
         ("scaled_1e-3", 1e-3, (0, 0, 0)), ("scaled_1e3", 1e3, (0, 0, 0))]
src = os.path.join(work, "original")
def rot(q):
    w, x, y, z = q
    n = math.sqrt(w*w + x*x + y*y + z*z); w, x, y, z = w/n, x/n, y/n, z/n
    return [[1-2*(y*y+z*z), 2*(x*y-w*z), 2*(x*z+w*y)], [2*(x*y+w*z), 1-2*(x*x+z*z), 2*(y*z-w*x)],
            [2*(x*z-w*y), 2*(y*z+w*x), 1-2*(x*x+y*y)]]
for name, a, T in cases:
    dst = os.path.join(work, name)
    sp = os.path.join(dst, "sparse", "0")
    os.makedirs(sp, exist_ok=True)
    if not os.path.exists(os.path.join(dst, "images")):
        os.symlink(os.path.abspath(os.path.join(src, "images")), os.path.join(dst, "images"))
    with open(os.path.join(src, "sparse/0/cameras.txt")) as f: cams = f.read()
    open(os.path.join(sp, "cameras.txt"), "w").write(cams)
    out, image_line = [], True
    for line in open(os.path.join(src, "sparse/0/images.txt")):
        if line.startswith("#"): out.append(line); continue
        if image_line:
            f = line.split()
            q = [float(v) for v in f[1:5]]; t = [float(v) for v in f[5:8]]; R = rot(q)
            t2 = [a*t[i] - sum(R[i][j]*T[j] for j in range(3)) for i in range(3)]
            out.append(" ".join([f[0]] + f[1:5] + [repr(v) for v in t2] + f[8:]) + "\n")
        else:
            out.append(line)
        image_line = not image_line
    open(os.path.join(sp, "images.txt"), "w").write("".join(out))
    out = []
    for line in open(os.path.join(src, "sparse/0/points3D.txt")):
        if line.startswith("#"): out.append(line); continue
        f = line.split()
        xyz = [repr(a*float(f[1+k]) + T[k]) for k in range(3)]
        out.append(" ".join([f[0]] + xyz + f[4:]) + "\n")
    open(os.path.join(sp, "points3D.txt"), "w").write("".join(out))
EOF

train() {  # BIN TAG NAME
  local bin=$1 tag=$2 name=$3 run="$work/runs_$2/$3"
  rm -rf "$run"
  mkdir -p "$work/runs_$tag"
  "$bin" train "$work/$name" --out "$run" --iterations "$iterations" --threads 1 --eval-every 0 \
    --save-at "$iterations" --checkpoint-every 0 --force > "$run.train.log" 2>&1 || echo "train $tag $name failed (see $run.train.log)"
  "$bin" export "$run" --out "$run.ply" --threads 1 --distill 0 --no-eval > "$run.export.log" 2>&1 || echo "export $tag $name failed"
}
while read -r name scale sx sy sz; do
  train "$hbgs" new "$name"
  [ -n "$old" ] && train "$old" old "$name"
done <<< "$cases"

python3 - "$work" "$iterations" "$cases" <<'EOF'
import json, math, os, struct, sys
work, it, cases = sys.argv[1], sys.argv[2], [l.split() for l in sys.argv[3].splitlines()]
def result(tag, name):
    try:
        r = json.load(open(os.path.join(work, "runs_" + tag, name, "results.json")))["ours_" + it]
        return r["PSNR"], r.get("train_seconds", float("nan")), r.get("mean_gaussians_per_view", float("nan"))
    except Exception:
        return None
def ply_mean(path):
    try:
        data = open(path, "rb").read()
    except OSError:
        return None
    head_end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:head_end].decode().splitlines()
    n = next(int(l.split()[2]) for l in header if l.startswith("element vertex"))
    props = [l.split()[2] for l in header if l.startswith("property float")]
    stride = 4 * len(props)
    ix, iy, iz = props.index("x"), props.index("y"), props.index("z")
    s = [0.0, 0.0, 0.0]
    for v in range(n):
        base = head_end + v * stride
        for k, i in enumerate((ix, iy, iz)):
            s[k] += struct.unpack_from("<f", data, base + 4 * i)[0]
    return [c / n for c in s]
orig = ply_mean(os.path.join(work, "runs_new", "original.ply"))
print(f"{'scene':<12} {'PSNR new':>9} {'PSNR old':>9} {'delta new':>9} {'train s':>8} {'PLY mean - expected (x extent)':>32}")
base = result("new", "original")
for name, a, sx, sy, sz in cases:
    new, old = result("new", name), result("old", name)
    m = ply_mean(os.path.join(work, "runs_new", name + ".ply"))
    off = "n/a"
    if m and orig:
        exp = [float(a) * orig[0] + float(sx), float(a) * orig[1] + float(sy), float(a) * orig[2] + float(sz)]
        off = "%.2e" % (math.dist(m, exp) / (float(a) * 6.64))
    print(f"{name:<12} {new[0] if new else float('nan'):9.3f} {old[0] if old else float('nan'):9.3f} "
          f"{(new[0] - base[0]) if new and base else float('nan'):9.3f} {new[1] if new else float('nan'):8.1f} {off:>32}")
EOF
