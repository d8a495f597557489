// SPDX-License-Identifier: MIT
// Initialisation from SfM points: the grid k-NN against brute force, and that a point's Gaussian
// renders in the point's colour.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "gs/scene_init.h"

TEST_CASE("mean_knn_distance matches brute force on clustered points") {
  std::mt19937_64 rng(5);
  std::normal_distribution<float> nrm(0, 1);
  std::uniform_real_distribution<float> u(-10, 10);
  std::vector<float> xyz;
  for (int c = 0; c < 20; ++c) {  // clusters of very different density, plus exact duplicates
    const float cx = u(rng), cy = u(rng), cz = u(rng), s = std::pow(10.0f, u(rng) / 5);
    for (int i = 0; i < 50; ++i) xyz.insert(xyz.end(), {cx + s * nrm(rng), cy + s * nrm(rng), cz + s * nrm(rng)});
  }
  xyz.insert(xyz.end(), {xyz[0], xyz[1], xyz[2]});
  const size_t n = xyz.size() / 3;
  const std::vector<float> d = gs::mean_knn_distance(xyz.data(), n, 3);
  for (size_t i = 0; i < n; ++i) {
    std::vector<float> all;
    for (size_t j = 0; j < n; ++j)
      if (j != i)
        all.push_back(std::sqrt(std::pow(xyz[3 * i] - xyz[3 * j], 2.0f) + std::pow(xyz[3 * i + 1] - xyz[3 * j + 1], 2.0f) +
                                std::pow(xyz[3 * i + 2] - xyz[3 * j + 2], 2.0f)));
    std::sort(all.begin(), all.end());
    const float expect = (all[0] + all[1] + all[2]) / 3;
    REQUIRE_MESSAGE(std::fabs(d[i] - expect) <= 1e-5f * std::max(1.0f, expect), "point " << i);
  }
}

TEST_CASE("gaussians_from_points: DC colour reproduces the point colour") {
  const float xyz[6] = {0, 0, 5, 1, 0, 5};
  const uint8_t rgb[6] = {255, 0, 128, 10, 20, 30};
  const gs::GaussianCloud c = gs::gaussians_from_points(xyz, rgb, 2, 0.8f);
  CHECK(c.size() == 2);
  for (int k = 0; k < 3; ++k) CHECK(0.5f + 0.28209479177387814f * c.sh[k] == doctest::Approx(rgb[k] / 255.0f).epsilon(1e-5));
  CHECK(c.log_scales[0] == doctest::Approx(0.0f).epsilon(1e-6));  // neighbour at distance 1
  std::vector<float> o;
  const gs::GaussianParams p = gs::activate(c, &o);
  CHECK(p.opacities[0] == doctest::Approx(0.8f));
}
