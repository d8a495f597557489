// SPDX-License-Identifier: MIT
// The standard 3DGS PLY layout (binary little-endian): x y z nx ny nz f_dc_0..2 f_rest_0..(3*(K-1)-1)
// opacity scale_0..2 rot_0..3, all float32; SH degree inferred from the f_rest count (0, 9, 24, 45).
// f_rest is channel-major in the file (all R coefficients, then G, then B); GaussianCloud::sh is
// [N, K, 3] with the DC term at k = 0.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/gaussians.h"
#include "gs/status.h"

namespace gs::io {

Expected<GaussianCloud> parse_splat_ply(const uint8_t* data, size_t size, const std::string& source);
Expected<GaussianCloud> read_splat_ply(const std::string& path);
std::vector<uint8_t> encode_splat_ply(const GaussianCloud& cloud);
Status write_splat_ply(const std::string& path, const GaussianCloud& cloud);  // atomic

}  // namespace gs::io
