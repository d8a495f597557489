#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# A stand-in for the colmap command that replays a saved SfM instead of running one, so a run that
# met a rare COLMAP reconstruction can be repeated exactly (COLMAP 3.8 does not repeat itself,
# docs/CAPTURE.md). REPLAY_DIR is a run's sfm_init folder (kept by tests/capture/e2e_pose_init_sfm.sh
# when it fails, as <work>.failed-<time>/sfm_init): each mapper call gets the reconstruction saved
# under its output folder's name (sparse, sparse_check1 ...), extraction and matching the saved
# database. Example (the e2e test's command, with the saved SfM):
#   hbgs synth --out scene --quiet
#   REPLAY_DIR=.../e2e_pose_init_sfm.failed-20261127-222335/sfm_init hbgs train scene --out run \
#     --iterations 200 --pose-noise barf:0.15 --optimize-poses --pose-init sfm --eval-every 0 \
#     --threads 2 --colmap scripts/colmap-replay.sh
set -euo pipefail
: "${REPLAY_DIR:?set REPLAY_DIR to a saved sfm_init folder}"
cmd=${1:-}; shift || true
out=""; db=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --output_path) out=$2; shift 2;;
    --database_path) db=$2; shift 2;;
    *) shift;;
  esac
done
case "$cmd" in
  feature_extractor|exhaustive_matcher|sequential_matcher) [[ -n "$db" ]] && cp "$REPLAY_DIR/database.db" "$db"; true;;
  mapper)
    saved="$REPLAY_DIR/$(basename "$out")"
    [[ -d "$saved" ]] || { echo "colmap-replay: no saved reconstruction $saved" >&2; exit 1; }
    mkdir -p "$out" && cp -r "$saved/." "$out/";;
  -h|--help|help) echo "COLMAP 3.8 replay";;
  *) echo "colmap-replay: unknown command $cmd" >&2; exit 1;;
esac
