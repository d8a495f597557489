// SPDX-License-Identifier: MIT
// Number formatting the jobs share in their messages and files (private to the jobs library).
#pragma once

#include <cstdio>
#include <string>

namespace gs::jobs {

// v with `digits` decimals ("%.*f").
inline std::string fixed(double v, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", digits, v);
  return buf;
}

// A fraction as a percentage with two decimals ("12.34%").
inline std::string pct(double fraction) { return fixed(100 * fraction, 2) + "%"; }

}  // namespace gs::jobs
