// SPDX-License-Identifier: MIT
// The project's seeded random numbers: SplitMix64 (Steele, Lea, Flood 2014), chosen because the
// same seed gives the same stream on every platform and compiler (std::*_distribution does not).
#pragma once

#include <cstdint>

namespace gs {

// SplitMix64's finaliser: a bijective 64-bit mix, used as a hash and as the generator's output.
inline uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// The generator: a Weyl sequence (golden-ratio increment) through mix64. The one SplitMix64 of
// hbgs: streams with their own seeding or distributions (pose noise, the synthetic scene) hold one.
struct SplitMix64 {
  uint64_t state = 0;
  uint64_t next() { return mix64(state += 0x9E3779B97F4A7C15ull); }
  // Uniform in [0, 1) from the top 53 bits.
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }
  // Uniform in the open interval (0, 1): the same 53 bits, centred in their step (log() safe).
  double uniform_open() { return (double(next() >> 11) + 0.5) * 0x1p-53; }
};

}  // namespace gs
