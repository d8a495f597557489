#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Speed and quality of two builds side by side, in one session on one machine (absolute times differ
# up to 2x between machines and hours, so every figure is read as a ratio NEW / OLD):
#   scripts/compare-speed.sh OLD_BUILD NEW_BUILD [OUT] [DATA]
# OLD_BUILD / NEW_BUILD are release build folders (bin/hbgs, bench/bench_train), for example the
# commit before a change built in a worktree beside this clone:
#   git worktree add ../baseline 53c8dcd && (cd ../baseline && cmake --preset release && cmake --build --preset release)
#   scripts/compare-speed.sh ../baseline/build/release build/release
# Runs, old and new alternately: bench_train --warmup 1000 --iterations 100 on snowmiku_plush (2
# threads, and 1 thread for the scaling; three times each, and the run with the median median is
# used, as one median moves by up to 25 % between runs on a shared VM), a default 3,000-iteration
# training of snowmiku_plush and of the built-in scene (the demo's), and the time-budget check of
# issue 23: T = the OLD build's training seconds for 1,000 iterations of each scene, then the NEW
# build with --time-budget T and 3T; and the new build's render forward (decode and splat, every
# view, best of 3 passes) of its 3,000-iteration snowmiku_plush model on 1 thread and on
# HBGS_SPEED_THREADS (2). Writes OUT/speed.md (table) and OUT/speed.json. About 37 minutes on 2
# cores; keep the machine otherwise idle.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
old=$(realpath "${1:?usage: compare-speed.sh OLD_BUILD NEW_BUILD [OUT] [DATA]}")
new=$(realpath "${2:?usage: compare-speed.sh OLD_BUILD NEW_BUILD [OUT] [DATA]}")
out=${3:-out/speed}
data=${4:-../shared/data}
threads=${HBGS_SPEED_THREADS:-2}
mkdir -p "$out"
out=$(realpath "$out")
for d in "$old" "$new"; do
  for f in bin/hbgs bench/bench_train; do
    [[ -x "$d/$f" ]] || { echo "compare-speed: $d/$f is missing (build the release preset there)" >&2; exit 1; }
  done
done
snow="$data/snowmiku_plush"
fox="$data/fox"
[[ -d "$snow" && -d "$fox" ]] || { echo "compare-speed: $snow or $fox not found (pass DATA)" >&2; exit 1; }
"$new/bin/hbgs" synth --out "$out/builtin" --force -q > /dev/null

bench() {  # side threads repetition
  local side=$1 t=$2 rep=$3 dir=${!1}
  "$dir/bench/bench_train" --dataset "$snow" --warmup 1000 --iterations 100 --threads "$t" \
    --json "$out/bench_${side}_t${t}_$rep.json" > "$out/bench_${side}_t${t}_$rep.log" 2>&1
}
train() {  # name build dataset iterations [args]
  local name=$1 dir=$2 ds=$3 it=$4
  shift 4
  rm -rf "$out/runs/$name"
  "$dir/bin/hbgs" train "$ds" --out "$out/runs/$name" --iterations "$it" --threads "$threads" --eval-every 0 \
    --save-at '' --checkpoint-every 0 -q "$@" > "$out/runs/$name.log" 2>&1
}
mkdir -p "$out/runs"
echo "compare-speed: bench_train (snowmiku_plush, 1,000 + 100 iterations)"
for rep in 1 2 3; do
  for t in "$threads" 1; do bench old "$t" "$rep"; bench new "$t" "$rep"; done
done
echo "compare-speed: 3,000-iteration trainings"
for side in old new; do
  train "snow3k_$side" "${!side}" "$snow" 3000
  train "builtin3k_$side" "${!side}" "$out/builtin" 3000
done
echo "compare-speed: render forward (the new snowmiku_plush model, every view, 1 and $threads threads)"
render() {  # threads repetition
  "$new/bin/hbgs" render "$out/runs/snow3k_new" --split all --threads "$1" -q --out "$out/render/t$1_$2" \
    > "$out/render/t$1_$2.log" 2>&1
}
rm -rf "$out/render"
mkdir -p "$out/render"
for rep in 1 2 3; do render "$threads" "$rep"; render 1 "$rep"; done
echo "compare-speed: time budgets (T = the old build's seconds for 1,000 iterations)"
for scene in snow fox builtin; do
  case $scene in snow) ds=$snow ;; fox) ds=$fox ;; builtin) ds=$out/builtin ;; esac
  train "${scene}1k_old" "$old" "$ds" 1000
  T=$(python3 -c "import json,sys; r=json.load(open(sys.argv[1])); print(list(r.values())[0]['train_seconds'])" \
      "$out/runs/${scene}1k_old/results.json")
  train "${scene}_T_new" "$new" "$ds" 100000000 --time-budget "$T"
  train "${scene}_3T_new" "$new" "$ds" 100000000 --time-budget "$(python3 -c "print(3 * $T)")"
done

python3 - "$out" <<'EOF'
import json, os, sys
out = sys.argv[1]
def res(name):
    r = json.load(open(os.path.join(out, 'runs', name, 'results.json')))
    return list(r.values())[0]
def bj(side, t):  # the repetition with the median iteration median (of 3, run alternately)
    runs = sorted((json.load(open(os.path.join(out, f'bench_{side}_t{t}_{rep}.json'))) for rep in (1, 2, 3)),
                  key=lambda b: b['median_ms'])
    return runs[1]
rows, js = [], {}
threads = int(os.environ.get('HBGS_SPEED_THREADS', '2'))
bo, bn = bj('old', threads), bj('new', threads)
bo1, bn1 = bj('old', 1), bj('new', 1)
rows.append(f"| bench_train median ms ({threads} threads) | {bo['median_ms']:.2f} | {bn['median_ms']:.2f} | {bn['median_ms'] / bo['median_ms']:.3f} |")
rows.append(f"| bench_train median ms (1 thread) | {bo1['median_ms']:.2f} | {bn1['median_ms']:.2f} | {bn1['median_ms'] / bo1['median_ms']:.3f} |")
rows.append(f"| 1 -> {threads} threads speed-up | {bo1['median_ms'] / bo['median_ms']:.2f}x | {bn1['median_ms'] / bn['median_ms']:.2f}x | |")
rows.append(f"| bench_train anchors / Gaussians per iteration | {bo['anchors']:.0f} / {bo['mean_gaussians']:.0f} | {bn['anchors']:.0f} / {bn['mean_gaussians']:.0f} | |")
for scene, label in (('snow3k', 'snowmiku_plush 3,000 it'), ('builtin3k', 'built-in 3,000 it')):
    o, n = res(scene + '_old'), res(scene + '_new')
    rows.append(f"| {label}: training s | {o['train_seconds']:.1f} | {n['train_seconds']:.1f} | {n['train_seconds'] / o['train_seconds']:.3f} |")
    rows.append(f"| {label}: test PSNR dB | {o['PSNR']:.3f} | {n['PSNR']:.3f} | {n['PSNR'] - o['PSNR']:+.3f} |")
    rows.append(f"| {label}: anchors, Gaussians per view | {o['anchors']}, {o['mean_gaussians_per_view']:.0f} | {n['anchors']}, {n['mean_gaussians_per_view']:.0f} | |")
    js[scene] = {'old': o, 'new': n}
for scene in ('snow', 'fox', 'builtin'):
    o = res(scene + '1k_old'); t1 = res(scene + '_T_new'); t3 = res(scene + '_3T_new')
    rows.append(f"| {scene}: old 1,000 it (T = {o['train_seconds']:.1f} s) / new --time-budget T / 3T: test PSNR dB | {o['PSNR']:.3f} | {t1['PSNR']:.3f} / {t3['PSNR']:.3f} | {t3['PSNR'] - t1['PSNR']:+.3f} (3T - T) |")
    rows.append(f"| {scene}: iterations that fit in T / 3T, anchors | 1000, {o['anchors']} | {t1['iterations']} / {t3['iterations']}, {t1['anchors']} / {t3['anchors']} | |")
    js[scene + '_budget'] = {'old_1k': o, 'T': t1, '3T': t3}
def render_ms(t):  # the best of three passes' median ms per view
    return min(json.load(open(os.path.join(out, 'render', f't{t}_{rep}', 'render.json')))['summary']['median_ms']
               for rep in (1, 2, 3))
r1, rn = render_ms(1), render_ms(threads)
rows.append(f"| render forward of the new snowmiku_plush model, median ms per view: 1 / {threads} threads | | {r1:.2f} / {rn:.2f} | {r1 / rn:.2f}x |")
js['render'] = {'ms_1_thread': r1, f'ms_{threads}_threads': rn}
md = "| measure | old | new | new / old |\n|---|---|---|---|\n" + "\n".join(rows) + "\n"
open(os.path.join(out, 'speed.md'), 'w').write(md)
json.dump({'bench': {'old': bo, 'new': bn, 'old_1t': bo1, 'new_1t': bn1}, **js}, open(os.path.join(out, 'speed.json'), 'w'), indent=1)
print(md)
EOF
