// SPDX-License-Identifier: MIT
// Private to the training job: its options as the run folder records them (run.json, the
// manifest's model options) and reads them back on --resume, and --save-at.
#pragma once

#include <string>
#include <vector>

#include "gs/jobs/train.h"
#include "gs/status.h"

namespace gs::jobs {

// --save-at: comma-separated iteration numbers, sorted, duplicates dropped.
Expected<std::vector<int>> parse_save_at(const std::string& text);
// run.json: the dataset and every option (eval, render and resume read it).
// run.json: the dataset and every option, and the scene frame the model is trained in when it is not
// the identity (gs/scene_frame.h; the model file holds it too).
std::string run_json(const TrainRunOptions& options, const SceneFrame& frame);
// The model options as JSON text (the run manifest records them beside the checkpoint).
std::string model_options_json(TrainRunOptions options);
// With resume, options not given explicitly come from run.json; model options given must match it
// (the checkpoint holds a model built with them).
Status apply_recorded_options(const std::string& run, TrainRunOptions* options);

}  // namespace gs::jobs
