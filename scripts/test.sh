#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Configures, builds and tests one CMake preset (default: release), the same way CI does.
#   scripts/test.sh [preset]     presets: release debug asan aarch64 armhf (see CMakePresets.json)
# GS_JOBS sets the build parallelism (default 2, what CI has). ctest's own summary is the last output,
# so the caller can read the result from the final lines.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

preset=${1:-release}
jobs=${GS_JOBS:-2}

t0=$SECONDS
cmake --preset "$preset"
cmake --build --preset "$preset" -j"$jobs"
echo "test.sh: configure + build of preset '$preset' took $((SECONDS - t0)) s"
# --no-tests=error: an empty selection (e.g. lost "qemu" labels) must fail, not pass silently.
# --no-label-summary keeps "100% tests passed, ..." within the last lines of the output.
ctest --preset "$preset" --no-tests=error --no-label-summary
