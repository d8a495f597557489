#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Checks hbgs as an installed library and as .deb packages, the way a user gets it (CI runs this
# after the native release build and the aarch64/armhf cross builds):
#   1. cmake --install of the release build into a temporary prefix; a tiny scene (hbgs synth) and
#      a model trained on it (hbgs train); a 3DGS PLY made from the scene's SfM points;
#   2. examples/ built against that prefix (find_package(hbgs)) and run: render_to_png (model, PLY,
#      the model exported as .splat and .spz by hbgs export, SfM points), register_image,
#      track_video (the scene's images as frames), train_with_progress;
#   3. examples/render_to_png built with plain `pkg-config --cflags --libs hbgs` and run;
#   4. cmake --install of the aarch64 build, examples/ cross-built against it and render_to_png run
#      under qemu-aarch64 on the same scene and model (armhf likewise under qemu-arm when built), the
#      installed hbgs-device trains 20 iterations on the scene with budget options, and it tracks
#      the scene's images in fixed point under qemu: its poses must be those of the native
#      hbgs-device within 0.001 degrees and 1e-5 of the scene radius (the same frames lost);
#   5. cpack -G DEB in each build folder: hbgs_<version>_{amd64,arm64,armhf}.deb, copied to
#      build/packages/; the arm64 package unpacked (dpkg-deb -x) and its hbgs render run under
#      qemu-aarch64; the amd64 package unpacked and examples/ built against it and run.
# Usage: scripts/check-install.sh [RELEASE_DIR [AARCH64_DIR [ARMHF_DIR]]]
#        (defaults build/release build/aarch64 build/armhf; a missing cross folder skips its steps)
# GS_JOBS: build parallelism (default 2). HBGS_KEEP_WORK=1 keeps the temporary folder.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
root=$PWD

release=$(realpath -m "${1:-build/release}")
aarch64=$(realpath -m "${2:-build/aarch64}")
armhf=$(realpath -m "${3:-build/armhf}")
jobs=${GS_JOBS:-2}
packages=$root/build/packages

work=$(mktemp -d "${TMPDIR:-/tmp}/hbgs-check-install.XXXXXX")
if [[ "${HBGS_KEEP_WORK:-0}" == 1 ]]; then
  echo "check-install: work folder $work (kept)"
else
  trap 'rm -rf "$work"' EXIT
fi

t_all=$SECONDS
t_step=$SECONDS
timings=()
step() {  # step "name": closes the previous step's timing, opens the next
  if [[ -n "${step_name:-}" ]]; then
    timings+=("$(printf '%4d s  %s' $((SECONDS - t_step)) "$step_name")")
  fi
  step_name=$1
  t_step=$SECONDS
  [[ -n "$step_name" ]] && echo "--- check-install: $step_name"
  return 0
}
fail() { echo "check-install: FAILED: $*" >&2; exit 1; }
need_file() { for f in "$@"; do [[ -s "$f" ]] || fail "missing or empty: $f"; done; }

[[ -x "$release/bin/hbgs" ]] || fail "$release/bin/hbgs is not built (build the release preset first)"
hbgs=$release/bin/hbgs
cross_cmake() {  # cross_cmake TRIPLE SRC BUILD PREFIX
  cmake -S "$2" -B "$3" -G Ninja -DCMAKE_BUILD_TYPE=Release \
        -DCMAKE_TOOLCHAIN_FILE="$root/toolchains/$1.cmake" -DCMAKE_PREFIX_PATH="$4" >"$3.configure.log" ||
    { cat "$3.configure.log"; fail "configuring $2 for $1"; }
}

# 1. Install, scene, model, PLY ------------------------------------------------------------------
step "native install into a temporary prefix"
cmake --install "$release" --prefix "$work/native" >/dev/null
need_file "$work/native/lib/cmake/hbgs/hbgsConfig.cmake" "$work/native/lib/cmake/hbgs/hbgsConfigVersion.cmake" \
          "$work/native/lib/cmake/hbgs/hbgsTargets.cmake" "$work/native/lib/pkgconfig/hbgs.pc" \
          "$work/native/include/gs/hbgs.h" "$work/native/include/gs/status.h" "$work/native/lib/libgs_base.a" \
          "$work/native/bin/hbgs" "$work/native/bin/hbgs-device"
"$work/native/bin/hbgs-device" --version >/dev/null || fail "installed hbgs-device does not run"
echo "installed: $(find "$work/native" -type f | wc -l) files, $(du -sh "$work/native" | cut -f1)"

step "scene (hbgs synth 64x48, 8 views) and model (hbgs train, 500 iterations)"
scene=$work/scene
run=$work/run
"$hbgs" synth --out "$scene" --width 64 --height 48 --views-arc 4 --views-orbit 4 --points 300 --seed 7 --quiet
"$hbgs" train "$scene" --out "$run" --iterations 500 --eval-every 0 --checkpoint-every 0 --save-at "" --quiet
need_file "$run/model.hbgs"
# A standard 3DGS PLY (SH degree 0) of the SfM points, for render_to_png's PLY path.
python3 - "$scene/sparse/0/points3D.txt" "$work/points.ply" <<'EOF'
import math, struct, sys
pts = []
for line in open(sys.argv[1]):
    f = line.split()
    if f and not f[0].startswith("#"):
        pts.append([float(v) for v in f[1:7]])
names = "x y z nx ny nz f_dc_0 f_dc_1 f_dc_2 opacity scale_0 scale_1 scale_2 rot_0 rot_1 rot_2 rot_3".split()
with open(sys.argv[2], "wb") as out:
    out.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % len(pts)).encode())
    out.write("".join("property float %s\n" % n for n in names).encode() + b"end_header\n")
    for x, y, z, r, g, b in pts:
        dc = [(c / 255.0 - 0.5) / 0.28209479177387814 for c in (r, g, b)]
        out.write(struct.pack("<17f", x, y, z, 0, 0, 0, *dc, math.log(0.8 / 0.2), *([math.log(0.03)] * 3), 1, 0, 0, 0))
print("points.ply: %d Gaussians" % len(pts))
EOF

# 2. examples/ against the install (find_package) ----------------------------------------------------
step "examples: native build against the install (find_package(hbgs))"
cmake -S examples -B "$work/ex-native" -G Ninja -DCMAKE_PREFIX_PATH="$work/native" >"$work/ex-native.log" ||
  { cat "$work/ex-native.log"; fail "configuring examples/ against $work/native"; }
cmake --build "$work/ex-native" -j"$jobs"

step "examples: native runs"
ex=$work/ex-native
"$ex/render_to_png" "$scene" "$run/model.hbgs" "$work/native_model.png" 1
"$ex/render_to_png" "$scene" "$work/points.ply" "$work/native_ply.png" 0002.png
"$ex/render_to_png" "$scene" points "$work/native_points.png" 3
need_file "$work/native_model.png" "$work/native_ply.png" "$work/native_points.png"
# Other splat formats through gs::io::read_gaussians: the model baked to .splat and .spz.
for ext in splat spz; do
  "$hbgs" export "$run" --out "$work/model.$ext" --distill 0 --no-eval >/dev/null
  "$ex/render_to_png" "$scene" "$work/model.$ext" "$work/native_$ext.png" 1 | tee "$work/render_$ext.txt"
  need_file "$work/native_$ext.png"
done
grep -q "model.spz: .spz, " "$work/render_spz.txt" || fail "render_to_png did not read model.spz as .spz"
"$ex/register_image" "$run/model.hbgs" "$scene" 3 4 | tee "$work/register.txt"
grep -q ": converged, pose" "$work/register.txt" || fail "register_image: no view converged"
# track_video on the scene's images as a frame folder (6 frames); while gs::pose::Tracker refuses
# (not built yet) the example is only built, and this says so.
if "$ex/track_video" "$run/model.hbgs" "$scene" "$scene/images" >"$work/track.txt" 2>&1; then
  cat "$work/track.txt"
  grep -q "^frame 5: " "$work/track.txt" || fail "track_video: no line for frame 5"
elif grep -q "the tracker is not built yet" "$work/track.txt"; then
  echo "check-install: track_video built; not run: gs::pose::Tracker is not built yet"
else
  cat "$work/track.txt" >&2
  fail "track_video"
fi
"$ex/train_with_progress" "$scene" "$work/run_example" 60 | tail -n 2
need_file "$work/run_example/model.hbgs"
# The on-device tracker (fixed point) on the scene's images, natively: the poses the ARM builds must
# give too (step 4).
"$work/native/bin/hbgs-device" track "$run/model.hbgs" "$scene/images" --out "$work/track-native" --threads 2 --quiet >/dev/null
need_file "$work/track-native/trajectory.txt"

# 3. pkg-config --------------------------------------------------------------------------------------
step "examples: render_to_png built with pkg-config --cflags --libs hbgs"
pc_flags=$(PKG_CONFIG_PATH="$work/native/lib/pkgconfig" pkg-config --cflags --libs hbgs)
echo "pkg-config: $pc_flags"
# shellcheck disable=SC2086  # the flags are a word list
g++ -std=c++17 -O2 examples/render_to_png.cpp -o "$work/render_to_png_pc" $pc_flags
"$work/render_to_png_pc" "$scene" "$run/model.hbgs" "$work/pc_model.png" 1
need_file "$work/pc_model.png"

# 4. Cross: examples/ against the cross installs, run under qemu ---------------------------------------
cross_examples() {  # cross_examples BUILD_DIR TRIPLE QEMU
  local dir=$1 triple=$2 qemu=$3 prefix=$work/$2
  step "$triple: install, examples cross-built against it, render_to_png under $qemu"
  cmake --install "$dir" --prefix "$prefix" >/dev/null
  need_file "$prefix/lib/cmake/hbgs/hbgsConfig.cmake" "$prefix/bin/hbgs"
  cross_cmake "$triple" examples "$work/ex-$triple" "$prefix"
  cmake --build "$work/ex-$triple" -j"$jobs"
  file "$work/ex-$triple/render_to_png" | grep -q "ARM" || fail "$work/ex-$triple/render_to_png is not an ARM binary"
  "$qemu" -L "/usr/$triple" "$work/ex-$triple/render_to_png" "$scene" "$run/model.hbgs" "$work/$triple-model.png" 1
  "$qemu" -L "/usr/$triple" "$work/ex-$triple/render_to_png" "$scene" "$work/points.ply" "$work/$triple-ply.png" 2
  need_file "$work/$triple-model.png" "$work/$triple-ply.png"
  # Training on the board, with the budget options (their ranges once refused every value on 32-bit
  # ARM, where size_t(1) << 32 is undefined).
  step "$triple: hbgs-device train (20 iterations, --max-anchors, --max-gaussians) under $qemu"
  "$qemu" -L "/usr/$triple" "$prefix/bin/hbgs-device" train "$scene" --out "$work/train-$triple" --iterations 20 \
    --max-anchors 2000 --max-gaussians 20000 --eval-every 0 --checkpoint-every 0 --save-at "" --threads 2 --quiet
  need_file "$work/train-$triple/model.hbgs"
  step "$triple: hbgs-device track (fixed point) under $qemu gives the native poses"
  "$qemu" -L "/usr/$triple" "$prefix/bin/hbgs-device" track "$run/model.hbgs" "$scene/images" --out "$work/track-$triple" \
    --threads 2 --quiet >/dev/null
  python3 - "$work/track-native" "$work/track-$triple" "$triple" <<'EOF' || fail "$triple: tracked poses differ from the native ones"
import math, sys
def read(d):
    poses = {}
    for line in open(d + "/trajectory.txt"):
        f = line.split()
        if f and not f[0].startswith("#"):
            poses[f[0]] = [float(v) for v in f[1:8]]
    lost = [l.split()[0] for l in open(d + "/lost.txt") if l.strip() and not l.startswith("#")]
    return poses, lost
(a, lost_a), (b, lost_b) = read(sys.argv[1]), read(sys.argv[2])
if sorted(a) != sorted(b) or sorted(lost_a) != sorted(lost_b):
    sys.exit("%s: frames placed %s natively, %s here; lost %s and %s" % (sys.argv[3], sorted(a), sorted(b), lost_a, lost_b))
centres = [p[:3] for p in a.values()]
mean = [sum(c[k] for c in centres) / len(centres) for k in range(3)]
radius = max(max(math.dist(c, mean) for c in centres), 1e-9)
rot = centre = 0.0
for t in a:
    # The angle between the two rotations: 2 atan2(|vector part of qa* qb|, |scalar part|), exact for
    # quaternions as printed (9 digits: not unit to the last bit, which would put acos(dot) at 3e-3 deg).
    (x1, y1, z1, w1), (x2, y2, z2, w2) = a[t][3:], b[t][3:]
    w = w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2
    v = (w1 * x2 - x1 * w2 - y1 * z2 + z1 * y2, w1 * y2 - y1 * w2 - z1 * x2 + x1 * z2, w1 * z2 - z1 * w2 - x1 * y2 + y1 * x2)
    rot = max(rot, math.degrees(2 * math.atan2(math.hypot(*v), abs(w))))
    centre = max(centre, math.dist(a[t][:3], b[t][:3]) / radius)
same = sum(a[t] == b[t] for t in a)
print("%s: %d frames placed (%d printed identically), %d lost, as natively; largest rotation difference %.2e deg, "
      "centre %.2e of the radius" % (sys.argv[3], len(a), same, len(lost_a), rot, centre))
if len(a) == 0 or rot > 0.001 or centre > 1e-5:
    sys.exit("%s: over 0.001 degrees or 1e-5 of the radius (or no frame placed)" % sys.argv[3])
EOF
}
if [[ -f "$aarch64/CMakeCache.txt" ]]; then
  cross_examples "$aarch64" aarch64-linux-gnu qemu-aarch64
else
  echo "check-install: $aarch64 not configured, aarch64 steps skipped"
fi
if [[ -f "$armhf/CMakeCache.txt" ]]; then
  cross_examples "$armhf" arm-linux-gnueabihf qemu-arm
else
  echo "check-install: $armhf not configured, armhf steps skipped"
fi

# 5. .deb packages -----------------------------------------------------------------------------------
mkdir -p "$packages"
make_deb() {  # make_deb BUILD_DIR DEB_ARCH -> prints the .deb path
  local dir=$1 arch=$2 version deb
  version=$(sed -n 's/^CMAKE_PROJECT_VERSION:STATIC=//p' "$dir/CMakeCache.txt")
  deb=hbgs_${version}_${arch}.deb
  rm -f "$dir/$deb"
  (cd "$dir" && cpack --config CPackConfig.cmake -G DEB >cpack.log 2>&1) || { cat "$dir/cpack.log" >&2; fail "cpack in $dir"; }
  [[ -s "$dir/$deb" ]] || fail "cpack in $dir did not make $deb"
  [[ "$(dpkg-deb -f "$dir/$deb" Architecture)" == "$arch" ]] || fail "$deb: Architecture is not $arch"
  cp "$dir/$deb" "$packages/"
  echo "$packages/$deb"
}
step "deb: amd64 package, unpacked, examples built against it"
deb_amd64=$(make_deb "$release" amd64)
mkdir "$work/deb-amd64"
dpkg-deb -x "$deb_amd64" "$work/deb-amd64"
cmake -S examples -B "$work/ex-deb" -G Ninja -DCMAKE_PREFIX_PATH="$work/deb-amd64/usr" >"$work/ex-deb.log" ||
  { cat "$work/ex-deb.log"; fail "configuring examples/ against the unpacked $deb_amd64"; }
grep -q "from $work/deb-amd64/usr/lib/cmake/hbgs" "$work/ex-deb.log" || fail "examples/ did not find hbgs in the unpacked package"
cmake --build "$work/ex-deb" -j"$jobs"
"$work/ex-deb/render_to_png" "$scene" "$run/model.hbgs" "$work/deb_model.png" 1
need_file "$work/deb_model.png"

if [[ -f "$aarch64/CMakeCache.txt" ]]; then
  step "deb: arm64 package, unpacked, its hbgs render under qemu-aarch64"
  deb_arm64=$(make_deb "$aarch64" arm64)
  mkdir "$work/deb-arm64"
  dpkg-deb -x "$deb_arm64" "$work/deb-arm64"
  qemu-aarch64 -L /usr/aarch64-linux-gnu "$work/deb-arm64/usr/bin/hbgs" --version
  qemu-aarch64 -L /usr/aarch64-linux-gnu "$work/deb-arm64/usr/bin/hbgs" render "$run" --out "$work/deb-arm64-render"
  need_file "$work/deb-arm64-render/render.json" "$work/deb-arm64-render/0000.png"
fi
if [[ -f "$armhf/CMakeCache.txt" ]]; then
  step "deb: armhf package, unpacked, its hbgs render under qemu-arm"
  deb_armhf=$(make_deb "$armhf" armhf)
  mkdir "$work/deb-armhf"
  dpkg-deb -x "$deb_armhf" "$work/deb-armhf"
  qemu-arm -L /usr/arm-linux-gnueabihf "$work/deb-armhf/usr/bin/hbgs" render "$scene" --out "$work/deb-armhf-render"
  need_file "$work/deb-armhf-render/render.json"
fi
step ""

echo "--- check-install: packages"
for deb in "$packages"/hbgs_*.deb; do
  printf '%s  %s bytes  Depends: %s\n' "$deb" "$(stat -c %s "$deb")" "$(dpkg-deb -f "$deb" Depends)"
done
echo "--- check-install: step timings (total $((SECONDS - t_all)) s)"
printf '%s\n' "${timings[@]}"
echo "check-install: all checks passed"
