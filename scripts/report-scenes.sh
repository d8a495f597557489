# SPDX-License-Identifier: MIT
# Sourced by on-device-report.sh and export-report.sh: the scenes they measure, each with a
# 3,000-iteration model. Needs `hbgs` and `threads` set by the caller.
#   report_scene SCENE SYNTH_DIR DEFAULT_RUN   sets `dataset` and `run` for SCENE (snowmiku_plush, fox
#   from ../shared/data, or synth: the built-in scene, generated into SYNTH_DIR when missing) and
#   trains the run when it has no model.hbgs; returns 1 (with a message) when the dataset is absent.
# HBGS_REPORT_RUNS="scene=RUN ..." names existing run folders instead of DEFAULT_RUN.
source scripts/scene-dataset.sh
report_scenes=(snowmiku_plush fox synth)
declare -A report_given=()
for kv in ${HBGS_REPORT_RUNS:-}; do report_given[${kv%%=*}]=${kv#*=}; done

report_scene() {
  local scene=$1 synth_dir=$2 default_run=$3
  dataset=$(scene_dataset "$scene" "$synth_dir")
  if [[ ! -d $dataset ]]; then echo "$(basename "$0"): $dataset not found, skipped" >&2; return 1; fi
  run=${report_given[$scene]:-$default_run}
  if [[ ! -f $run/model.hbgs ]]; then
    echo "== $scene: training 3,000 iterations"
    "$hbgs" train "$dataset" --out "$run" --iterations 3000 --threads "$threads" --quiet --force
  fi
}
