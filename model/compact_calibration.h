// SPDX-License-Identifier: MIT
// Private to gs_model: the scan behind compacting a model (compact_convert.cpp): the decoder run
// over every calibration camera, giving which anchors are visible, which keep a Gaussian (opacity
// > 0) and the maximum |activation| per channel of every MLP (the int8 kernels' ranges).
#pragma once

#include <cstdint>
#include <vector>

#include "gs/camera.h"
#include "gs/model/compact_model.h"
#include "gs/model/hybrid_model.h"
#include "gs/status.h"

namespace gs::platform { class ThreadPool; }

namespace gs::model::detail {

struct CalibrationScan {
  std::vector<uint8_t> seen, kept;  // [M]: visible in some view; some Gaussian with opacity > 0
  std::vector<uint8_t> kept_gaussian;  // [M, k]: neural Gaussian j of anchor i has opacity > 0 in some view
  ActivationRanges ranges[kMlpCount];
};

// Runs the decoder (with pre-activation outputs) on every camera: visibility, opacity > 0 per
// anchor, and the maximum |activation| per channel of every MLP. pool may be null.
Status scan_views(const HybridModel& m, const std::vector<Camera>& cams, platform::ThreadPool* pool, CalibrationScan* out);

// How much the rendered training views move when an anchor's offsets move, measured with the
// renderer's own backward: for every camera, the image-space gradient of a seeded random +-1
// pattern (so its expected square is the sum over pixels of the squared Jacobian, Hutchinson's
// estimator) is taken to the Gaussian means and from there to the offsets (times exp of the
// anchor's offset log-scale). out[a]: that squared gradient summed over the views, the anchor's
// Gaussians and the 3 axes; 0 for an anchor none of whose Gaussians is drawn. pool may be null.
Status offset_sensitivity_scan(const HybridModel& m, const std::vector<Camera>& cams, platform::ThreadPool* pool,
                               std::vector<double>* out);

}  // namespace gs::model::detail
