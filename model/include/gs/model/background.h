// SPDX-License-Identifier: MIT
// The background colour a model is trained and rendered on (issue 15, object captures): a fixed
// colour (black, as the 3DGS default; white, as for NeRF-synthetic scenes; any r,g,b), or a random
// colour per training iteration, the usual practice for masked data because it leaves the model no
// colour it could paint into the empty space instead of being transparent there.
#pragma once

#include <string>

#include "gs/status.h"

namespace gs::model {

struct Background {
  bool random = false;      // a uniform random colour per training iteration
  float rgb[3] = {0, 0, 0}; // the fixed colour; with random, the colour evaluation and renders use
};

// "black", "white", "random" (evaluated on black) or "r,g,b" with each value in [0, 1].
Expected<Background> parse_background(const std::string& text);
// The text parse_background reads back to the same background ("black", "white", "random",
// "0.5,0.25,1").
std::string background_name(const Background& b);

}  // namespace gs::model
