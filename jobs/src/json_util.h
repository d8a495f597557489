// SPDX-License-Identifier: MIT
// JSON pieces the jobs share (private to the jobs library: nlohmann::json stays out of the public
// headers): evaluation files in the 3DGS schema and pose errors.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gs/model/evaluate.h"
#include "gs/pose/pose.h"
#include "gs/status.h"

namespace gs::jobs {

// Merges the evaluation `r` as `method` into <dir>/results.json and per_view.json (other methods
// already in them are kept; an unreadable file is replaced and *note says so), in the 3DGS schema:
// results.json = {"<method>": {"SSIM": s, "PSNR": p, "LPIPS": l}} and per_view.json =
// {"<method>": {"SSIM": {name: s}, "PSNR": {...}, "LPIPS": {...}}}; LPIPS is left out when it was
// not computed; with masks, "PSNR_masked", "alpha_MAE" and "alpha_IoU" too. extra: members added
// to results.json's method object (timings, model size, LPIPS backbone label). This is the one
// writer of both files.
Status write_eval_files(const std::string& dir, const std::string& method, const model::EvalResult& r,
                        const nlohmann::json& extra, std::string* note = nullptr);

nlohmann::json pose_errors_json(const pose::PoseErrors& e, bool per_view, const std::vector<std::string>& names = {});

}  // namespace gs::jobs
