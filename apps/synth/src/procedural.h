// SPDX-License-Identifier: MIT
// Seeded randomness for the synthetic scene: a counter-free hash, a small RNG and 3D value noise.
// Everything here is plain integer/double arithmetic so a seed gives the same scene on every run
// and for any thread count (no std::*_distribution, whose output is implementation-defined).
#pragma once

#include <cmath>
#include <cstdint>

#include "gs/hash.h"
#include "gs/random.h"

namespace hbgs::synth::detail {

using gs::mix64;  // SplitMix64's finaliser (gs/random.h): hash and RNG step

// gs::hash_combine (gs/hash.h) then mix64: every output bit depends on every input bit.
inline uint64_t hash_combine(uint64_t h, uint64_t v) { return mix64(gs::hash_combine(h, v)); }

// Uniform double in [0, 1) from the top 53 bits of a hash.
inline double to_unit(uint64_t h) { return double(h >> 11) * (1.0 / 9007199254740992.0); }

class Rng {
 public:
  explicit Rng(uint64_t seed) : gen_{mix64(seed ^ 0x5851f42d4c957f2dULL)} {}
  uint64_t next() { return gen_.next(); }
  double uniform() { return gen_.uniform(); }  // = to_unit(next())
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  // Integer in [0, n); the modulo bias (n / 2^64) is irrelevant here.
  int below(int n) { return int(next() % uint64_t(n)); }
  // Standard normal via Box-Muller (one value per call; the second is dropped for simplicity).
  double normal() {
    double u1 = 1.0 - uniform();  // (0, 1], keeps log finite
    double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  gs::SplitMix64 gen_;  // the one SplitMix64 (gs/random.h)
};

// Lattice value in [0, 1) at an integer point; the seed selects an independent noise field.
// One multiply-xorshift mix over an odd-multiplier combination of the coordinates: plenty for
// texture noise, and a third of the cost of chaining hash_combine per coordinate.
inline double lattice(uint64_t seed, int64_t x, int64_t y, int64_t z) {
  uint64_t h = seed ^ (uint64_t(x) * 0x9e3779b97f4a7c15ULL) ^ (uint64_t(y) * 0xc2b2ae3d27d4eb4fULL) ^
               (uint64_t(z) * 0x165667b19e3779f9ULL);
  return to_unit(mix64(h));
}

inline double smooth(double t) { return t * t * (3.0 - 2.0 * t); }
inline double lerp(double a, double b, double t) { return a + (b - a) * t; }

// Trilinear value noise with smoothstep weights; one lattice cell per unit of the input, output [0, 1).
inline double value_noise(uint64_t seed, double x, double y, double z) {
  double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  int64_t ix = int64_t(fx), iy = int64_t(fy), iz = int64_t(fz);
  double tx = smooth(x - fx), ty = smooth(y - fy), tz = smooth(z - fz);
  double c[2][2];
  for (int dz = 0; dz < 2; ++dz) {
    for (int dy = 0; dy < 2; ++dy) {
      double a = lattice(seed, ix, iy + dy, iz + dz);
      double b = lattice(seed, ix + 1, iy + dy, iz + dz);
      c[dz][dy] = lerp(a, b, tx);
    }
  }
  return lerp(lerp(c[0][0], c[0][1], ty), lerp(c[1][0], c[1][1], ty), tz);
}

// Fractal sum of `octaves` value-noise layers (frequency x2, amplitude /2), normalised to [0, 1).
inline double fbm(uint64_t seed, double x, double y, double z, int octaves) {
  double sum = 0, amp = 1, norm = 0, f = 1;
  for (int o = 0; o < octaves; ++o) {
    sum += amp * value_noise(hash_combine(seed, uint64_t(o)), x * f, y * f, z * f);
    norm += amp;
    amp *= 0.5;
    f *= 2.0;
  }
  return sum / norm;
}

}  // namespace hbgs::synth::detail
