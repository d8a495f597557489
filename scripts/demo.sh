#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The README's main job: install dependencies (apt), build, then `hbgs demo`: generate the built-in
# ground-truth scene (Embree ray tracing -> COLMAP dataset), train the model on it, evaluate the
# held-out views (PSNR, SSIM, LPIPS-Alex) and write renders, the PSNR-vs-time plot and report.md.
#   scripts/demo.sh [output folder, default: out]   (extra hbgs demo options via HBGS_DEMO_ARGS)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=${1:-out}

scripts/install-deps.sh --no-cross
cmake --preset release
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=build/release/bin/hbgs
echo
"$hbgs" --version
# shellcheck disable=SC2086
"$hbgs" demo --out "$out/demo" ${HBGS_DEMO_ARGS:-}
