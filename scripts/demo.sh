#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The README's main job: install dependencies (apt), build, generate the built-in ground-truth
# scene (Embree ray tracing -> COLMAP dataset), initialise Gaussians from its SfM points, render
# every view, and print timings and where the images went.
#   scripts/demo.sh [output folder, default: out]
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
out=${1:-out}

scripts/install-deps.sh --no-cross
cmake --preset release
cmake --build --preset release -j"${GS_JOBS:-2}" --target hbgs
hbgs=build/release/bin/hbgs
echo
"$hbgs" --version
"$hbgs" synth --out "$out/default_scene" --force
"$hbgs" render "$out/default_scene" --out "$out/default_render"
