// SPDX-License-Identifier: MIT
// Private helpers of the splat format readers and writers (io/splat/): the limits, the
// 8-bit colour/alpha conventions the formats share, and the checks every writer and reader runs
// on a GaussianCloud (array sizes, finiteness, usable quaternions).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "../io_util.h"
#include "gs/constants.h"
#include "gs/gaussians.h"
#include "gs/platform/file.h"
#include "gs/status.h"

namespace gs::io::detail {

// The most splats any reader accepts (the 3DGS PLY reader's limit): 100 M splats are 3.2 GB as
// .splat and 25 GB as float PLY, beyond any scene hbgs renders on a CPU.
constexpr uint64_t kMaxSplats = 100'000'000;

using gs::kShC0;  // colour = 0.5 + kShC0 * dc (the 3DGS convention)

// 1/sqrt(2): the bound of a unit quaternion's three smallest components (smallest-three packing in
// .spz v3 and compressed.ply).
constexpr double kSqrtHalf = 0.70710678118654752440;

inline double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

// v rounded to the nearest integer and clamped to [0, max_code] (NaN gives 0; writers refuse NaN
// before they get here).
inline uint32_t quantize_clamped(double v, uint32_t max_code) {
  if (!(v > 0)) return 0;
  if (v >= double(max_code)) return max_code;
  return uint32_t(std::floor(v + 0.5));
}

// The opacity logit of an 8-bit alpha a/255. 0 and 255 would give -inf and +inf, so alpha is
// clamped half a step inside (0, 1): the decoded alpha stays within the half step (0.5/255) that
// rounding already allows.
inline float logit_from_alpha8(uint32_t a) {
  const double alpha = std::min(std::max(double(a) / 255.0, 0.5 / 255.0), 254.5 / 255.0);
  return float(std::log(alpha / (1.0 - alpha)));
}

// q = (w, x, y, z) scaled to unit length in double; false (and the identity (1, 0, 0, 0) in out)
// when its norm is zero or not finite.
inline bool normalized_quaternion(const float* q, double out[4]) {
  const double n = std::sqrt(double(q[0]) * q[0] + double(q[1]) * q[1] + double(q[2]) * q[2] + double(q[3]) * q[3]);
  const bool usable = n > 0 && std::isfinite(n);
  for (int k = 0; k < 4; ++k) out[k] = usable ? double(q[k]) / n : (k == 0 ? 1.0 : 0.0);
  return usable;
}

// Sizes agree with size() and sh_degree, the count is within kMaxSplats, every value is finite
// and every quaternion is non-zero. `what` prefixes the message (a path or a format name).
Status check_cloud_for_writing(const GaussianCloud& cloud, const std::string& what);

// A cloud of n splats at sh_degree fits this platform's size_t (a 32-bit build cannot hold the
// largest counts the formats declare); checked before allocating.
Status check_cloud_fits(uint64_t n, int sh_degree, const std::string& source);

// Every value of a cloud just read is finite; the message names the source, splat and field.
Status check_cloud_finite(const GaussianCloud& cloud, const std::string& source);

// A whole splat file read and given to parse(data, size, path); exceptions become a Status.
// 64 GiB at most: the largest count any reader accepts times the widest record fits below it.
template <class Parse>
Expected<GaussianCloud> read_and_parse(const std::string& path, Parse&& parse) {
  return guarded(path, [&]() -> Expected<GaussianCloud> {
    auto bytes = platform::read_file(path, uint64_t(1) << 36);
    if (!bytes.ok()) return bytes.status();
    return parse(bytes->data(), bytes->size(), path);
  });
}

}  // namespace gs::io::detail
