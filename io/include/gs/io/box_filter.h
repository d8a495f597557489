// SPDX-License-Identifier: MIT
// The one box (area) filter of hbgs: each output pixel is the weighted sum of the source pixels
// its cell covers. One loop serves integer s x s blocks (training targets and composites, the
// image-feature pyramid, registration levels, frame sharpness) and any ratio (resize_area:
// fractional weights at the cell borders). Callers bring the pixel access and the accumulator, so
// integer, float and double sums each keep their own arithmetic and summation order. No allocation.
#pragma once

#include <algorithm>
#include <cstddef>

namespace gs::io {

// The axes of the filter: which source pixels each output cell covers, with what weight. Each
// has cell(i), the positions [begin, end) of cell i; index(j), the source pixel at position j;
// weight(cell, j), 1 or the overlap (<= 0: not a tap).
struct AxisCell {
  int begin, end;
  double a, b;  // FractionalAxis: the cell's bounds in source pixels
};

// Integer cells of s pixels, weight 1 each: cell i is [i s, i s + s); a cell reaching past the
// edge reuses the last pixel (only when out * s > size, e.g. a pyramid level of a 1 px image).
struct BlockAxis {
  int size, s;
  AxisCell cell(int i) const { return {i * s, i * s + s, 0, 0}; }
  int index(int j) const { return std::min(j, size - 1); }
  double weight(const AxisCell&, int) const { return 1.0; }
};

// `out` cells of whole pixels, weight 1: cell i is [i size / out, (i + 1) size / out) in integer
// division, at least one pixel (thumbnails of any size).
struct SpanAxis {
  int size, out;
  AxisCell cell(int i) const {
    const int first = i * size / out;
    return {first, std::min(size, std::max(first + 1, (i + 1) * size / out)), 0, 0};
  }
  int index(int j) const { return j; }
  double weight(const AxisCell&, int) const { return 1.0; }
};

// `out` cells over the whole axis: cell i is [i step, (i + 1) step), step = size / out, the pixels
// at its borders weighted by their overlap (resampling to any size; nothing past the edge).
struct FractionalAxis {
  int size;
  double step;
  FractionalAxis(int size_, int out) : size(size_), step(double(size_) / double(out)) {}
  AxisCell cell(int i) const {
    const double a = i * step, b = (i + 1) * step;  // >= 0: int() is floor, and ceil(b) below
    const int ceil_b = int(b) + (b > double(int(b)) ? 1 : 0);
    return {int(a), std::min(size, ceil_b), a, b};
  }
  int index(int j) const { return j; }
  double weight(const AxisCell& c, int j) const { return std::min(c.b, double(j + 1)) - std::max(c.a, double(j)); }
};

// For each output pixel (x, y) of [out_h, out_w], row-major, starting from Acc{}: for each row tap
// (sy, wy) of y in order, add(acc, sx, sy, wx) for each column tap (sx, wx) of x in order, then
// end_row(acc, wy); last, store(y * out_w + x, acc). end_row lets a caller weight whole rows (a
// separable sum); callers that sum every tap alike leave it empty.
template <class Acc, class XAxis, class YAxis, class Add, class EndRow, class Store>
inline void area_filter(const XAxis& xs, const YAxis& ys, int out_w, int out_h, Add&& add, EndRow&& end_row,
                        Store&& store) {
  for (int y = 0; y < out_h; ++y) {
    const AxisCell cy = ys.cell(y);
    for (int x = 0; x < out_w; ++x) {
      const AxisCell cx = xs.cell(x);
      Acc acc{};
      for (int j = cy.begin; j < cy.end; ++j) {
        const double wy = ys.weight(cy, j);
        if (!(wy > 0)) continue;
        for (int i = cx.begin; i < cx.end; ++i) {
          const double wx = xs.weight(cx, i);
          if (wx > 0) add(acc, xs.index(i), ys.index(j), wx);
        }
        end_row(acc, wy);
      }
      store(size_t(y) * size_t(out_w) + size_t(x), acc);
    }
  }
}

// Unweighted cells (BlockAxis, SpanAxis): add(acc, sx, sy) for each source pixel of the cell, row
// by row, then store(output index, acc).
template <class Acc, class XAxis, class YAxis, class Add, class Store>
inline void box_filter(const XAxis& xs, const YAxis& ys, int out_w, int out_h, Add&& add, Store&& store) {
  area_filter<Acc>(
      xs, ys, out_w, out_h, [&](Acc& acc, int sx, int sy, double) { add(acc, sx, sy); }, [](Acc&, double) {}, store);
}
// Integer s x s blocks of a [height, width] image into [out_h, out_w] (normally height / s and
// width / s, remainder dropped).
template <class Acc, class Add, class Store>
inline void box_filter(int width, int height, int s, int out_w, int out_h, Add&& add, Store&& store) {
  box_filter<Acc>(BlockAxis{width, s}, BlockAxis{height, s}, out_w, out_h, add, store);
}

}  // namespace gs::io
