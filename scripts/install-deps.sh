#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs what hbgs needs to build and test on Debian 12 (bookworm): compilers, CMake/Ninja, the
# header and library dependencies, the capture/ingest tools (FFmpeg, libcamera, COLMAP), Chromium
# (headless, for the report page's test), and the ARM
# cross compilers + qemu-user for the cross test runs.
# Idempotent: exits early when everything is already installed. Never upgrades and never enables
# multiarch (both would change unrelated host packages).
#   scripts/install-deps.sh            everything (what CI uses)
#   scripts/install-deps.sh --no-cross skip the ARM cross compilers and qemu-user (~500 MB)
set -euo pipefail

native=(cmake ninja-build g++ pkg-config libeigen3-dev libxsimd-dev libstb-dev doctest-dev libembree-dev libtbb-dev
        libbenchmark-dev libcli11-dev nlohmann-json3-dev zlib1g-dev libzstd-dev  # .spz: gzip (v2, v3), ZSTD (v4)
        libturbojpeg0-dev  # bench/bench_mjpeg only: hbgs's MJPEG decoding measured against libjpeg-turbo
        dpkg-dev file python3  # cpack -G DEB (dpkg-shlibdeps) and scripts/check-install.sh
        clang libclang-rt-14-dev  # libFuzzer and ThreadSanitizer builds (scripts/fuzz.sh, scripts/tsan.sh)
        chromium)  # headless, for the report page's test (tests/report: the viewer's screenshot vs hbgs's render)
# Capture and ingestion: video decoding (FFmpeg's libraries), libcamera, and the ffmpeg and colmap
# commands (`hbgs ingest` runs COLMAP; the end-to-end ingest test encodes its video with ffmpeg).
capture=(libavformat-dev libavcodec-dev libavutil-dev libswscale-dev libcamera-dev ffmpeg colmap)
cross=(g++-aarch64-linux-gnu g++-arm-linux-gnueabihf qemu-user)

packages=("${native[@]}" "${capture[@]}")
case "${1:-}" in
  --no-cross) ;;
  "") packages+=("${cross[@]}") ;;
  *) echo "usage: $0 [--no-cross]" >&2; exit 2 ;;
esac

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q '^install ok installed$'; then
    missing+=("$p")
  fi
done
if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#packages[@]} packages already installed"
  exit 0
fi

sudo=()
if [[ $(id -u) -ne 0 ]]; then sudo=(sudo); fi
apt_opts=(-y -q -o DPkg::Lock::Timeout=600)
echo "install-deps: installing ${missing[*]}"
"${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get "${apt_opts[@]}" update
"${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get "${apt_opts[@]}" install --no-install-recommends "${missing[@]}"
