# SPDX-License-Identifier: MIT
# Sourced by the real-data sweeps (ablation.sh, ba-real-poses.sh): builds `hbgs` (release preset) and
# sets hbgs (its path), scenes (every COLMAP scene in $data, by folder name) and lpips (the
# --lpips-weights option when $data/lpips_alex exists). Needs $data; exits when it has no scene.
cmake --preset release >/dev/null
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=$(realpath build/release/bin/hbgs)
scenes=()
for d in "$data"/*/; do
  [[ -f "$d/sparse/0/points3D.txt" || -f "$d/sparse/0/points3D.bin" ]] && scenes+=("$(basename "$d")")
done
[[ ${#scenes[@]} -gt 0 ]] || { echo "$(basename "$0"): no COLMAP scene in $data" >&2; exit 1; }
lpips=()
[[ -d "$data/lpips_alex" ]] && lpips=(--lpips-weights "$data/lpips_alex")
