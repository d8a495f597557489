// SPDX-License-Identifier: MIT
// Mathematical constants shared across the layers (C++17 has no std::numbers), defined once.
#pragma once

namespace gs {

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace gs
