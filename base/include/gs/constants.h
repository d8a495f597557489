// SPDX-License-Identifier: MIT
// Mathematical constants shared across the layers (C++17 has no std::numbers), defined once.
#pragma once

namespace gs {

inline constexpr double kPi = 3.14159265358979323846;
// The degree-0 real spherical harmonic, 1 / (2 sqrt(pi)): colour = 0.5 + kShC0 * dc (3DGS).
inline constexpr double kShC0 = 0.28209479177387814;

}  // namespace gs
