// SPDX-License-Identifier: MIT
// Camera trajectories in the TUM RGB-D benchmark's text format: one line per pose,
// "timestamp tx ty tz qx qy qz qw", the camera's centre and its camera-to-world rotation as a unit
// quaternion (scalar last) in the world frame; '#' starts a comment line. hbgs keeps world-to-camera
// poses (gs/camera.h), so the functions convert both ways.
#pragma once

#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/scene_frame.h"
#include "gs/status.h"

namespace gs::io {

struct TimedPose {
  double time = 0;  // seconds
  Pose pose;        // world-to-camera
};

// Writes the trajectory atomically (9 significant digits). frame: the model's scene frame, whose
// poses are written back in the user's frame (the identity leaves them as they are).
Status write_tum_trajectory(const std::vector<TimedPose>& poses, const std::string& path,
                            const SceneFrame& frame = SceneFrame{});
// The same text, for streaming a line at a time (no newline at the end).
std::string tum_line(const TimedPose& pose, const SceneFrame& frame = SceneFrame{});
// Reads a trajectory. Errors name the file and line: not 8 numbers, a value that is not finite, a
// quaternion of norm outside [0.5, 2] (others are normalised).
Expected<std::vector<TimedPose>> read_tum_trajectory(const std::string& path);
Expected<std::vector<TimedPose>> parse_tum_trajectory(const std::string& text, const std::string& source);

}  // namespace gs::io
