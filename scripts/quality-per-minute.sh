#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Test PSNR after a few minutes of training, two builds side by side on one machine (issue 23's
# "after 1, 3 and 10 minutes" table):
#   scripts/quality-per-minute.sh OLD_BUILD NEW_BUILD [OUT] [DATA]
# NEW_BUILD trains with --time-budget M minutes. OLD_BUILD may predate --time-budget, so it trains
# the iteration count that fills about M minutes at its own pace: its seconds for 1,000 iterations
# (measured here once per scene, or taken from OUT/pace_SCENE.txt) scaled to M minutes, times 0.93
# because an iteration gets dearer as the model grows (snowmiku_plush, 53c8dcd: 1,000 iterations
# in 32.5 s, 4,800 in 167.7 s). Its actual training seconds are in the table beside its PSNR.
# Environment: HBGS_QPM_MINUTES (default "10 3 1": the longest first, so a stopped run still has
# them), HBGS_QPM_SCENES (default "snowmiku_plush fox sceaux_castle"), HBGS_QPM_THREADS (2).
# Finished runs are reused (delete OUT/runs/NAME to redo one). Time: about 2 x 14 minutes per
# scene with the defaults; keep the machine otherwise idle (the budgets are wall-clock seconds).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
old=$(realpath "${1:?usage: quality-per-minute.sh OLD_BUILD NEW_BUILD [OUT] [DATA]}")
new=$(realpath "${2:?usage: quality-per-minute.sh OLD_BUILD NEW_BUILD [OUT] [DATA]}")
out=${3:-out/quality_per_minute}
data=${4:-../shared/data}
minutes=${HBGS_QPM_MINUTES:-10 3 1}
scenes=${HBGS_QPM_SCENES:-snowmiku_plush fox sceaux_castle}
threads=${HBGS_QPM_THREADS:-2}
for d in "$old" "$new"; do
  [[ -x "$d/bin/hbgs" ]] || { echo "quality-per-minute: $d/bin/hbgs is missing (build the release preset there)" >&2; exit 1; }
done
mkdir -p "$out/runs"
out=$(realpath "$out")

result() {  # run-name field
  python3 -c "import json,sys; r=list(json.load(open(sys.argv[1])).values())[0]; print(r[sys.argv[2]])" \
    "$out/runs/$1/results.json" "$2"
}
train() {  # name build dataset iterations [args]
  local name=$1 dir=$2 ds=$3 it=$4
  shift 4
  if [[ -f "$out/runs/$name/results.json" ]]; then return; fi
  rm -rf "$out/runs/$name"
  echo "quality-per-minute: $name" >&2
  "$dir/bin/hbgs" train "$ds" --out "$out/runs/$name" --iterations "$it" --threads "$threads" --eval-every 0 \
    --save-at '' --checkpoint-every 0 -q "$@" > "$out/runs/$name.log" 2>&1 ||
    { echo "quality-per-minute: $name failed, see $out/runs/$name.log" >&2; exit 1; }
}

for scene in $scenes; do
  [[ -d "$data/$scene" ]] || { echo "quality-per-minute: $data/$scene not found (pass DATA)" >&2; exit 1; }
  pace="$out/pace_$scene.txt"
  if [[ ! -s "$pace" ]]; then
    train "${scene}_pace_old" "$old" "$data/$scene" 1000
    result "${scene}_pace_old" train_seconds > "$pace"
  fi
done
for m in $minutes; do
  for scene in $scenes; do
    it=$(python3 -c "import sys; print(max(100, round(float(sys.argv[1]) * 60 / float(sys.argv[2]) * 1000 * 0.93)))" \
         "$m" "$(cat "$out/pace_$scene.txt")")
    train "${scene}_${m}m_old" "$old" "$data/$scene" "$it"
    train "${scene}_${m}m_new" "$new" "$data/$scene" 100000000 --time-budget "${m}m"
  done
done

python3 - "$out" "$scenes" "$minutes" <<'EOF'
import json, os, sys
out, scenes, minutes = sys.argv[1], sys.argv[2].split(), sys.argv[3].split()
def res(name):
    p = os.path.join(out, 'runs', name, 'results.json')
    return list(json.load(open(p)).values())[0] if os.path.exists(p) else None
rows = []
for scene in scenes:
    for m in sorted(minutes, key=float):
        o, n = res(f'{scene}_{m}m_old'), res(f'{scene}_{m}m_new')
        if not o or not n:
            continue
        rows.append(f"| {scene} | {m} min | {o['PSNR']:.3f} dB ({o.get('iterations', '?')} it, {o['train_seconds']:.1f} s) | "
                    f"{n['PSNR']:.3f} dB ({n['iterations']} it, {n['train_seconds']:.1f} s) | {n['PSNR'] - o['PSNR']:+.3f} |")
md = ("| scene | budget | old: test PSNR (iterations, training s) | new --time-budget: test PSNR (iterations, s) | new - old |\n"
      "|---|---|---|---|---|\n" + "\n".join(rows) + "\n")
open(os.path.join(out, 'quality_per_minute.md'), 'w').write(md)
print(md)
EOF
