// SPDX-License-Identifier: MIT
// Cameras as users give them (intrinsics "fx fy cx cy", a pose "qw qx qy qz tx ty tz" read in
// double) and as a dataset holds them (its one shared camera, scaled to an image's size): what
// `hbgs register` (--camera, --init) and `hbgs track` (--intrinsics, --start-pose) share. Private
// to the jobs library.
#pragma once

#include <string>

#include "gs/camera.h"
#include "gs/io/colmap.h"
#include "gs/status.h"

namespace gs::jobs {

// The 7 numbers of a pose text (qw qx qy qz tx ty tz) that pose::parse_pose accepted, in double,
// the quaternion normalised: far from the origin float would lose the translation.
void pose_text_numbers(const std::string& text, double q[4], double t[3]);

// "fx fy cx cy" (spaces and/or commas): four finite numbers, focal lengths positive. Errors start
// with `flag` (e.g. "--camera"). Sets fx, fy, cx, cy only.
Status parse_intrinsics_text(const std::string& text, const std::string& flag, PinholeIntrinsics* K);

// The one camera all views of a dataset use (identical parameters; PINHOLE or OPENCV as
// io::read_dataset_files gives it, fx fy cx cy first either way). *note is set when it has lens
// distortion (the frames are then used as pinhole images). Errors end with `hint` (what to pass
// instead, e.g. "pass --camera \"fx fy cx cy\"").
Status shared_dataset_camera(const io::DatasetFiles& files, const std::string& dataset, const std::string& hint,
                             io::ColmapCamera* camera, std::string* note);

// True when width x height is the camera's size scaled uniformly: the same aspect within 0.1 %, or
// the height the dataset loader's max_width rounding gives for that width.
bool is_uniform_scale(const io::ColmapCamera& camera, int width, int height);

// The camera's fx, fy, cx, cy scaled to an image of width x height (each axis by its own ratio).
PinholeIntrinsics scaled_intrinsics(const io::ColmapCamera& camera, int width, int height);

}  // namespace gs::jobs
