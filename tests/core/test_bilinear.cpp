// SPDX-License-Identifier: MIT
// The one bilinear sampler (gs/bilinear.h): exact at pixel centres, exact on affine images (values
// and derivatives), edge handling of the neighbourhood (clamped, or refused), float and double.
#include <doctest/doctest.h>

#include <cstdint>
#include <vector>

#include "gs/bilinear.h"

namespace gs {
namespace {

// [h, w, 3] image whose channel k is the affine function base[k] + gx[k] x + gy[k] y of the pixel
// index (x, y), so bilinear interpolation reproduces it exactly.
std::vector<double> affine_image(int w, int h) {
  std::vector<double> im(size_t(w) * size_t(h) * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int k = 0; k < 3; ++k) im[(size_t(y) * size_t(w) + size_t(x)) * 3 + size_t(k)] = 10.0 * k + (k + 1) * x - 0.5 * y;
  return im;
}

TEST_CASE("bilinear: exact at pixel centres and on affine images, with the derivatives") {
  const int w = 7, h = 5;
  const std::vector<double> im = affine_image(w, h);
  double c[3], cu[3], cv[3];
  // Pixel centre (3, 2) sits at (u, v) = (3.5, 2.5).
  REQUIRE(sample_bilinear_rgb(im.data(), w, h, 3.5, 2.5, false, c, cu, cv));
  for (int k = 0; k < 3; ++k) CHECK(c[k] == im[(2 * size_t(w) + 3) * 3 + size_t(k)]);
  for (double u : {0.5, 1.25, 3.9, 6.49})
    for (double v : {0.5, 2.75, 4.499}) {
      REQUIRE(sample_bilinear_rgb(im.data(), w, h, u, v, false, c, cu, cv));
      for (int k = 0; k < 3; ++k) {
        CHECK(c[k] == doctest::Approx(10.0 * k + (k + 1) * (u - 0.5) - 0.5 * (v - 0.5)).epsilon(1e-12));
        CHECK(cu[k] == doctest::Approx(k + 1).epsilon(1e-12));
        CHECK(cv[k] == doctest::Approx(-0.5).epsilon(1e-12));
      }
    }
}

TEST_CASE("bilinear: positions past the edge are clamped or refused") {
  const int w = 4, h = 3;
  std::vector<uint8_t> im(size_t(w) * size_t(h) * 3);
  for (size_t i = 0; i < im.size(); ++i) im[i] = uint8_t(7 * i % 251);
  double c[3] = {-1, -1, -1};
  // Not clamped: the 2 x 2 neighbourhood must lie inside (x in [0, w - 1), y in [0, h - 1)).
  CHECK_FALSE(sample_bilinear_rgb(im.data(), w, h, 0.49, 1.0, false, c));
  CHECK_FALSE(sample_bilinear_rgb(im.data(), w, h, 2.0, 2.5, false, c));
  CHECK(c[0] == -1);  // untouched
  // Clamped: a corner far outside gives the corner pixel.
  REQUIRE(sample_bilinear_rgb(im.data(), w, h, -5.0, 100.0, true, c));
  for (int k = 0; k < 3; ++k) CHECK(c[k] == im[(2 * size_t(w) + 0) * 3 + size_t(k)]);
  // The neighbourhood itself: floor for negative positions, both columns clamped to the edge.
  const BilinearCell<float> q = bilinear_cell(-0.25f, 2.5f, w, h);
  CHECK(q.x0 == 0);
  CHECK(q.x1 == 0);
  CHECK(q.fx == 0.75f);
  CHECK(q.y0 == 2);
  CHECK(q.y1 == 2);
  CHECK(q.fy == 0.5f);
  const BilinearCell<double> r = bilinear_cell(1.5, 0.0, w, h);
  CHECK(r.x0 == 1);
  CHECK(r.x1 == 2);
  CHECK(r.fx == 0.5);
  CHECK(r.y0 == 0);
  CHECK(r.y1 == 1);
  CHECK(r.fy == 0.0);
  // The blend weighs rows last: value at (fx, fy) = (0.25, 0.5) of a = 0, b = 4, d = 8, e = 12.
  const BilinearCell<float> m{0, 1, 0, 1, 0.25f, 0.5f};
  CHECK(bilinear_blend(m, uint8_t(0), uint8_t(4), uint8_t(8), uint8_t(12)) == 5.0f);
}

}  // namespace
}  // namespace gs
