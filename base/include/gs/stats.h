// SPDX-License-Identifier: MIT
// Small summary statistics shared by the reports (pose errors, timings, ICP and alignment moves).
#pragma once

#include <algorithm>
#include <vector>

namespace gs {

// The arithmetic mean; 0 for no values.
inline double mean(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v;
  return values.empty() ? 0.0 : sum / double(values.size());
}

// The median (the mean of the middle two for an even count); 0 for no values.
inline double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t m = values.size() / 2;
  return values.size() % 2 ? values[m] : 0.5 * (values[m - 1] + values[m]);
}

// The upper median (the larger middle value for an even count), found in place with nth_element:
// reorders `values`. 0 for no values.
inline double upper_median_in_place(std::vector<double>& values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + long(mid), values.end());
  return values[mid];
}

}  // namespace gs
