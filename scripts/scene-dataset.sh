# SPDX-License-Identifier: MIT
# Sourced by the scripts that measure every scene. Needs `hbgs` set by the caller.
#   scene_dataset SCENE SYNTH_DIR   prints SCENE's dataset folder: ../shared/data/SCENE, or for
#   synth the built-in scene, generated into SYNTH_DIR when missing. The caller checks that it exists.
scene_dataset() {
  local scene=$1 synth_dir=$2
  if [[ $scene == synth ]]; then
    [[ -d $synth_dir ]] || "$hbgs" synth --out "$synth_dir" --quiet >&2
    echo "$synth_dir"
  else
    echo "../shared/data/$scene"
  fi
}
