// SPDX-License-Identifier: MIT
// Static rANS over bytes (14-bit probabilities, 32-bit state, byte renormalisation): a general
// entropy coder for byte streams with skewed statistics, hbgs's own. The compact model file
// (gs/model/compact_model.h) codes each quantised channel as one stream. It knows nothing of the
// model: it lives in gs_model because that is the lowest layer that uses it (standard C++ only, so
// it can move down to gs_base unchanged when a lower layer needs it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace gs::model::detail {

// Appends the stream for symbols[0..n): its frequency table (varints, runs of absent symbols
// coded as 0 and the run length), the payload length and the payload. Nothing for n = 0.
void rans_encode_bytes(const uint8_t* symbols, size_t n, std::vector<uint8_t>* out);
// Decodes exactly n symbols from data[*pos ..], advancing *pos; checks every bound and the final
// state, and returns false (with *error) on malformed input.
bool rans_decode_bytes(const uint8_t* data, size_t size, size_t* pos, size_t n, uint8_t* symbols, std::string* error);

}  // namespace gs::model::detail
