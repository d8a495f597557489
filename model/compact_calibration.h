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

}  // namespace gs::model::detail
