// SPDX-License-Identifier: MIT
// Parsing and naming backgrounds (gs/model/background.h).
#include "gs/model/background.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace gs::model {

Expected<Background> parse_background(const std::string& text) {
  Background b;
  if (text == "black") return b;
  if (text == "white") {
    b.rgb[0] = b.rgb[1] = b.rgb[2] = 1.0f;
    return b;
  }
  if (text == "random") {
    b.random = true;
    return b;
  }
  const std::string usage = "background '" + text + "': expected black, white, random or r,g,b with each value in [0, 1]";
  size_t pos = 0;
  for (int c = 0; c < 3; ++c) {
    const size_t end = c < 2 ? text.find(',', pos) : text.size();
    if (end == std::string::npos) return invalid_argument(usage);
    const std::string part = text.substr(pos, end - pos);
    char* stop = nullptr;
    const float v = part.empty() ? NAN : std::strtof(part.c_str(), &stop);
    if (part.empty() || stop != part.c_str() + part.size() || !std::isfinite(v) || v < 0.f || v > 1.f)
      return invalid_argument(usage + " ('" + part + "' is not a number in [0, 1])");
    b.rgb[c] = v;
    pos = end + 1;
  }
  return b;
}

std::string background_name(const Background& b) {
  if (b.random) return "random";
  if (b.rgb[0] == 0 && b.rgb[1] == 0 && b.rgb[2] == 0) return "black";
  if (b.rgb[0] == 1 && b.rgb[1] == 1 && b.rgb[2] == 1) return "white";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g,%.9g,%.9g", double(b.rgb[0]), double(b.rgb[1]), double(b.rgb[2]));
  return buf;
}

}  // namespace gs::model
