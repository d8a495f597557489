// SPDX-License-Identifier: MIT
// The GaussianCloud checks shared by the splat format writers and readers (splat_common.h).
#include "splat_common.h"

#include <cmath>
#include <limits>

namespace gs::io::detail {
namespace {

struct Field {
  const char* name;
  const std::vector<float>* values;
  size_t per_splat;
};

// The cloud's arrays with their names as the messages give them.
std::vector<Field> fields_of(const GaussianCloud& c) {
  return {{"position", &c.means, 3},
          {"log scale", &c.log_scales, 3},
          {"rotation", &c.quats, 4},
          {"opacity logit", &c.opacity_logits, 1},
          {"SH coefficient", &c.sh, size_t(sh_coeff_count(c.sh_degree)) * 3}};
}

Status first_non_finite(const GaussianCloud& c, const std::string& prefix) {
  for (const Field& f : fields_of(c))
    for (size_t i = 0; i < f.values->size(); ++i)
      if (!std::isfinite((*f.values)[i]))
        return invalid_argument(prefix + "splat " + std::to_string(i / f.per_splat) + ": " + f.name + " " +
                                std::to_string(i % f.per_splat) + " is " + std::to_string((*f.values)[i]) +
                                " (NaN and infinity cannot be stored)");
  return Status::Ok();
}

}  // namespace

Status check_cloud_for_writing(const GaussianCloud& c, const std::string& what) {
  if (c.sh_degree < 0 || c.sh_degree > 3)
    return invalid_argument(what + ": SH degree " + std::to_string(c.sh_degree) + " (0..3 supported)");
  const size_t n = c.size();
  if (n > kMaxSplats)
    return invalid_argument(what + ": " + std::to_string(n) + " splats, more than the " + std::to_string(kMaxSplats) +
                            " the readers accept");
  for (const Field& f : fields_of(c))
    if (f.values->size() != n * f.per_splat)
      return invalid_argument(what + ": GaussianCloud " + f.name + " array has " + std::to_string(f.values->size()) +
                              " values, " + std::to_string(n) + " splats need " + std::to_string(n * f.per_splat));
  GS_RETURN_IF_ERROR(first_non_finite(c, what + ": "));
  for (size_t i = 0; i < n; ++i) {
    double q[4];
    if (!normalized_quaternion(&c.quats[4 * i], q))
      return invalid_argument(what + ": splat " + std::to_string(i) + ": rotation quaternion is zero");
  }
  return Status::Ok();
}

Status check_cloud_fits(uint64_t n, int sh_degree, const std::string& source) {
  const uint64_t floats = n * (3 + 3 + 4 + 1 + uint64_t(sh_coeff_count(sh_degree)) * 3);
  if (floats > std::numeric_limits<size_t>::max() / sizeof(float))
    return unsupported(source + ": " + std::to_string(n) + " splats need more memory than this build can address");
  return Status::Ok();
}

Status check_cloud_finite(const GaussianCloud& c, const std::string& source) {
  Status st = first_non_finite(c, source + ": ");
  if (st.ok()) return st;
  return parse_error(st.message());
}

}  // namespace gs::io::detail
