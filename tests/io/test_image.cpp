// SPDX-License-Identifier: MIT
// Image IO tests: PNG/JPEG decode, hostile inputs (truncated, garbage, huge headers), exact area
// downscaling, float -> 8-bit conversion, and PNG file round trips.
#define STBI_WRITE_NO_STDIO
#include <stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "gs/io/image.h"
#include "gs/platform/file.h"
#include "io_test_util.h"

namespace gs::io {
namespace {

using test::check_error;

Image8 random_image(int w, int h, int c, uint32_t seed) {
  std::mt19937 rng(seed);
  Image8 img{w, h, c, std::vector<uint8_t>(size_t(w) * size_t(h) * size_t(c))};
  for (uint8_t& p : img.pixels) p = uint8_t(rng());
  return img;
}

// A smooth image: JPEG reproduces it within a few levels.
Image8 gradient_image(int w, int h) {
  Image8 img{w, h, 3, std::vector<uint8_t>(size_t(w) * size_t(h) * 3)};
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = &img.pixels[(size_t(y) * size_t(w) + size_t(x)) * 3];
      p[0] = uint8_t(255 * x / (w - 1)), p[1] = uint8_t(255 * y / (h - 1)), p[2] = 128;
    }
  return img;
}

// A baseline grey JPEG of `blocks` 8x8 blocks in one row, made byte by byte: one quantisation table
// (16-bit steps when `sixteen_bit`) whose DC step is dc_step, one-code Huffman tables, and every
// block's DC difference +32767 (category 15, fifteen 1 bits) then end-of-block. Valid syntax; the
// DC predictor stb multiplies by the step grows by 32767 a block.
std::vector<uint8_t> dc_ramp_jpeg(int blocks, uint16_t dc_step, bool sixteen_bit) {
  std::vector<uint8_t> j = {0xff, 0xd8};
  auto segment = [&](uint8_t marker, const std::vector<uint8_t>& payload) {
    const size_t len = payload.size() + 2;
    j.insert(j.end(), {0xff, marker, uint8_t(len >> 8), uint8_t(len & 0xff)});
    j.insert(j.end(), payload.begin(), payload.end());
  };
  std::vector<uint8_t> dqt = {uint8_t(sixteen_bit ? 0x10 : 0x00)};
  for (int i = 0; i < 64; ++i) {
    const uint16_t step = i == 0 ? dc_step : 1;
    if (sixteen_bit) dqt.push_back(uint8_t(step >> 8));
    dqt.push_back(uint8_t(step & 0xff));
  }
  segment(0xdb, dqt);
  const int width = 8 * blocks;
  segment(0xc0, {8, 0, 8, uint8_t(width >> 8), uint8_t(width & 0xff), 1, 1, 0x11, 0});  // 8 bits, 8 rows, 1 component
  std::vector<uint8_t> dc = {0x00, 1}, ac = {0x10, 1};  // one code of 1 bit each
  dc.insert(dc.end(), 15, 0), ac.insert(ac.end(), 15, 0);
  dc.push_back(15), ac.push_back(0x00);  // DC: category 15; AC: end of block
  segment(0xc4, dc);
  segment(0xc4, ac);
  segment(0xda, {1, 1, 0x00, 0, 63, 0});
  std::string bits;
  for (int b = 0; b < blocks; ++b) bits += "0" + std::string(15, '1') + "0";
  bits.append((8 - bits.size() % 8) % 8, '1');
  for (size_t i = 0; i < bits.size(); i += 8) {
    j.push_back(uint8_t(std::stoi(bits.substr(i, 8), nullptr, 2)));
    if (j.back() == 0xff) j.push_back(0x00);  // byte stuffing
  }
  j.insert(j.end(), {0xff, 0xd9});
  return j;
}

std::vector<uint8_t> png_of(const Image8& img) {
  auto png = encode_png(img);
  REQUIRE(png.ok());
  return *png;
}

TEST_CASE("PNG encode/decode round trip with channel conversion") {
  const Image8 rgb = random_image(37, 23, 3, 1);
  const auto png = png_of(rgb);
  auto back = decode_image(png.data(), png.size(), 3, "rgb.png");
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  CHECK(back->width == 37);
  CHECK(back->height == 23);
  CHECK(back->channels == 3);
  CHECK(back->pixels == rgb.pixels);

  const Image8 gray = random_image(5, 4, 1, 2);
  const auto gpng = png_of(gray);
  auto as_rgb = decode_image(gpng.data(), gpng.size(), 3, "gray.png");
  REQUIRE(as_rgb.ok());
  for (size_t i = 0; i < gray.pixels.size(); ++i)
    for (int c = 0; c < 3; ++c) CHECK(as_rgb->pixels[i * 3 + size_t(c)] == gray.pixels[i]);

  auto rgba = decode_image(png.data(), png.size(), 4, "rgb.png");
  REQUIRE(rgba.ok());
  CHECK(rgba->pixels[3] == 255);
  check_error(decode_image(png.data(), png.size(), 2, "rgb.png").status(), {"2 channels"});
  check_error(encode_png(Image8{4, 4, 3, std::vector<uint8_t>(10)}).status(), {"pixel buffer size"});
}

TEST_CASE("JPEG decodes close to the encoded image") {
  const Image8 img = gradient_image(64, 48);
  std::vector<uint8_t> jpg;
  auto sink = [](void* ctx, void* data, int size) {
    auto* out = static_cast<std::vector<uint8_t>*>(ctx);
    out->insert(out->end(), static_cast<uint8_t*>(data), static_cast<uint8_t*>(data) + size);
  };
  REQUIRE(stbi_write_jpg_to_func(sink, &jpg, 64, 48, 3, img.pixels.data(), 95) != 0);
  auto back = decode_image(jpg.data(), jpg.size(), 3, "g.jpg");
  REQUIRE_MESSAGE(back.ok(), back.status().to_string());
  REQUIRE(back->pixels.size() == img.pixels.size());
  double mae = 0;
  for (size_t i = 0; i < img.pixels.size(); ++i) mae += std::abs(int(back->pixels[i]) - int(img.pixels[i]));
  mae /= double(img.pixels.size());
  // Quality 95 on a smooth gradient: typically ~1 level; 3 leaves room for encoder differences.
  CHECK(mae < 3.0);
}

TEST_CASE("hostile image bytes give errors and not crashes") {
  const auto png = png_of(random_image(40, 30, 3, 3));
  for (size_t n : {size_t(0), size_t(5), size_t(8), size_t(20), size_t(33), size_t(60), png.size() / 2, png.size() - 13}) {
    auto r = decode_image(png.data(), n, 3, "cut.png");
    check_error(r.status(), {"cut.png"});
  }
  const std::vector<uint8_t> garbage = {'G', 'I', 'F', '8', '9', 'a', 1, 2, 3, 4, 5, 6, 7, 8};
  check_error(decode_image(garbage.data(), garbage.size(), 3, "x.gif").status(), {"x.gif", "unknown image format"});

  // IHDR width/height (big-endian, bytes 16..23) patched to 100000 x 100000: refused from the header.
  auto huge = png;
  for (int k : {16, 20}) huge[size_t(k)] = 0, huge[size_t(k) + 1] = 0x01, huge[size_t(k) + 2] = 0x86, huge[size_t(k) + 3] = 0xA0;
  check_error(decode_image(huge.data(), huge.size(), 3, "huge.png").status(), {"huge.png", "100000x100000"});

  std::mt19937 rng(5);
  for (int trial = 0; trial < 300; ++trial) {
    auto bytes = png;
    for (int k = 0; k < 4; ++k) bytes[8 + rng() % (bytes.size() - 8)] = uint8_t(rng());
    auto r = decode_image(bytes.data(), bytes.size(), 3, "fuzz.png");
    if (r.ok()) CHECK(r->pixels.size() == size_t(r->width) * size_t(r->height) * 3);
  }
}

TEST_CASE("fuzz findings: JPEG Huffman tables over 256 codes and PNG chunks longer than the file are refused before stb") {
  // Inputs found by fuzz/fuzz_image (kept in its seed corpus): Debian 12's stb_image wrote past a
  // Huffman table's arrays, sized a buffer from a PNG chunk's declared length (1.8 GB), and copied an
  // empty IDAT chunk to a null buffer (memcpy(NULL, ..., 0), undefined).
  const struct {
    const char* file;
    const char* expect;
  } cases[] = {{"dht_overflow.jpg", "more than 256"},
               {"dht_overflow_truncated.jpg", "declares 1183 codes, more than 256"},
               {"dht_overflow_header_cut.jpg", "more than 256"},
               {"png_huge_idat.png", "corrupt PNG: chunk 'IDAT'"},
               {"scan_undefined_table.jpg", "uses a Huffman table that no DHT segment defines"},
               {"huff_decode_negative_index.jpg", "uses a Huffman table that no DHT segment defines"},
               {"dequant_undefined_table.jpg", "the scan at byte 181 uses quantisation table 0, which no DQT segment before it defines"},
               {"empty_idat_before_data.png", "an empty IDAT chunk at byte 3349 before any image data"}};
  for (const auto& c : cases) {
    const std::string path = std::string(GS_SOURCE_DIR) + "/fuzz/corpus/image/" + c.file;
    const Expected<std::vector<uint8_t>> bytes = platform::read_file(path);
    REQUIRE_MESSAGE(bytes.ok(), bytes.status().to_string());
    const Expected<Image8> img = decode_image(bytes->data(), bytes->size(), 3, c.file);
    REQUIRE_FALSE(img.ok());
    CHECK_MESSAGE(img.status().message().find(c.expect) != std::string::npos, img.status().message());
  }
}

TEST_CASE("fuzz finding: a JPEG DC predictor times its quantisation step past int decodes (wrapping), not undefined") {
  // fuzz/fuzz_image found stb_image's `dc * dequant[0]` overflowing int (the step came from a table
  // no DQT defined, refused above; here the tables are defined). stb_impl.cpp is compiled with
  // -fwrapv, so under the sanitisers these decode to (garbage) pixels instead of undefined
  // behaviour; refusing 16-bit tables would not do: an 8-bit step of 255 overflows after 258 blocks.
  const struct {
    const char* what;
    int blocks;
    uint16_t step;
    bool sixteen_bit;
  } cases[] = {{"16-bit table, 2 blocks", 2, 65535, true}, {"8-bit table, 300 blocks", 300, 255, false}};
  for (const auto& c : cases) {
    CAPTURE(c.what);
    const std::vector<uint8_t> jpeg = dc_ramp_jpeg(c.blocks, c.step, c.sixteen_bit);
    const Expected<Image8> img = decode_image(jpeg.data(), jpeg.size(), 1, "dc_ramp.jpg");
    REQUIRE_MESSAGE(img.ok(), img.status().to_string());
    CHECK(img->width == 8 * c.blocks);
    CHECK(img->height == 8);
  }
  // The same file kept in the fuzz corpus as a seed.
  const std::string path = std::string(GS_SOURCE_DIR) + "/fuzz/corpus/image/dc_overflow_16bit_table.jpg";
  const Expected<std::vector<uint8_t>> kept = platform::read_file(path);
  REQUIRE_MESSAGE(kept.ok(), kept.status().to_string());
  CHECK(*kept == dc_ramp_jpeg(2, 65535, true));
}

TEST_CASE("read_image and write_png round trip through a file") {
  test::TempDir dir;
  const Image8 img = random_image(9, 7, 3, 4);
  REQUIRE(write_png(dir / "a.png", img).ok());
  auto back = read_image(dir / "a.png");
  REQUIRE(back.ok());
  CHECK(back->pixels == img.pixels);
  check_error(read_image(dir / "missing.png").status(), {dir / "missing.png"});
  test::write_text(dir / "bad.png", "definitely not an image");
  check_error(read_image(dir / "bad.png").status(), {dir / "bad.png", "unknown image format"});
}

TEST_CASE("resize_area: integer ratios give the exact rounded block mean") {
  for (int k : {2, 3}) {
    const Image8 src = random_image(12 * k, 7 * k, 3, uint32_t(10 + k));
    const Image8 dst = resize_area(src, 12, 7);
    REQUIRE(dst.width == 12);
    REQUIRE(dst.height == 7);
    for (int y = 0; y < 7; ++y)
      for (int x = 0; x < 12; ++x)
        for (int c = 0; c < 3; ++c) {
          int sum = 0;
          for (int j = 0; j < k; ++j)
            for (int i = 0; i < k; ++i) sum += src.pixels[((size_t(y * k + j) * size_t(src.width)) + size_t(x * k + i)) * 3 + size_t(c)];
          const int expect = (2 * sum + k * k) / (2 * k * k);  // round half up
          CHECK(dst.pixels[(size_t(y) * 12 + size_t(x)) * 3 + size_t(c)] == expect);
        }
  }
}

TEST_CASE("resize_area: non-integer ratios keep constants and the mean") {
  Image8 flat{10, 7, 1, std::vector<uint8_t>(70, 77)};
  const Image8 d = resize_area(flat, 3, 4);
  REQUIRE(d.pixels.size() == 12);
  for (uint8_t p : d.pixels) CHECK(p == 77);
  const Image8 src = random_image(30, 20, 1, 9);
  const Image8 small = resize_area(src, 7, 6);
  double m0 = 0, m1 = 0;
  for (uint8_t p : src.pixels) m0 += p;
  for (uint8_t p : small.pixels) m1 += p;
  // Area weights sum to the same total; only per-pixel rounding (<= 0.5) moves the mean.
  CHECK(std::abs(m0 / 600.0 - m1 / 42.0) <= 0.5);
  CHECK(resize_area(src, 0, 5).empty());
}

TEST_CASE("box filter axes: the source pixels and weights of each cell") {
  // Integer blocks: cell i is [2i, 2i + 2); past the edge the last pixel is reused.
  const BlockAxis blocks{5, 2};
  const AxisCell b2 = blocks.cell(2);
  CHECK(b2.begin == 4);
  CHECK(b2.end == 6);
  CHECK(blocks.index(4) == 4);
  CHECK(blocks.index(5) == 4);
  CHECK(blocks.weight(b2, 5) == 1.0);
  // Whole-pixel spans: 10 pixels into 4 cells at i * 10 / 4, and at least one pixel per cell when
  // there are more cells than pixels.
  const SpanAxis spans{10, 4};
  const int begins[4] = {0, 2, 5, 7}, ends[4] = {2, 5, 7, 10};
  for (int i = 0; i < 4; ++i) {
    CHECK(spans.cell(i).begin == begins[i]);
    CHECK(spans.cell(i).end == ends[i]);
  }
  const SpanAxis tiny{3, 8};
  for (int i = 0; i < 8; ++i) {
    CHECK(tiny.cell(i).end - tiny.cell(i).begin == 1);
    CHECK(tiny.cell(i).begin == i * 3 / 8);
  }
  // Fractional cells: 10 pixels into 4 cells of 2.5; cell 1 is [2.5, 5): pixel 2 by half, 3 and 4 whole.
  const FractionalAxis frac(10, 4);
  const AxisCell f1 = frac.cell(1);
  CHECK(f1.begin == 2);
  CHECK(f1.end == 5);
  CHECK(frac.weight(f1, 2) == 0.5);
  CHECK(frac.weight(f1, 3) == 1.0);
  CHECK(frac.weight(f1, 4) == 1.0);
  // Every cell's weights add up to its width, for ratios that are not binary fractions too.
  for (const auto& [size, out] : {std::pair{10, 4}, {7, 3}, {100, 7}, {13, 13}, {5, 1}}) {
    const FractionalAxis axis(size, out);
    double total = 0;
    for (int i = 0; i < out; ++i) {
      const AxisCell c = axis.cell(i);
      CHECK(c.begin >= 0);
      CHECK(c.end <= size);
      double w = 0;
      for (int j = c.begin; j < c.end; ++j) w += std::max(0.0, axis.weight(c, j));
      CHECK(w == doctest::Approx(double(size) / out).epsilon(1e-12));
      total += w;
    }
    CHECK(total == doctest::Approx(double(size)).epsilon(1e-12));
  }
}

TEST_CASE("box filter: visiting order, row weights, and the block means against direct sums") {
  // area_filter visits a cell's rows in order, each row's columns in order, then end_row(row weight).
  std::vector<int> visits;
  std::vector<double> row_weights;
  area_filter<int>(
      FractionalAxis(5, 2), BlockAxis{4, 2}, 2, 2,
      [&](int&, int x, int y, double) { visits.push_back(10 * y + x); },
      [&](int&, double wy) { row_weights.push_back(wy); }, [](size_t, int) {});
  // Output (x 0, y 0): rows 0, 1; columns 0, 1, 2 (2 by half). Output (1, 0): columns 2, 3, 4.
  const std::vector<int> expect = {0, 1, 2, 10, 11, 12, 2, 3, 4, 12, 13, 14, 20, 21, 22, 30, 31, 32, 22, 23, 24, 32, 33, 34};
  CHECK(visits == expect);
  CHECK(row_weights == std::vector<double>(8, 1.0));

  // box_downsample_rgb / rgb8 against the mean written out, including a pyramid level of a 1 px wide
  // image (out 1 x 1 from 1 x 3: the block reuses the last column and row).
  const Image8 src = random_image(11, 9, 3, 21);
  for (int s : {1, 2, 3, 4}) {
    const int ow = 11 / s, oh = 9 / s;
    std::vector<float> f(size_t(ow) * size_t(oh) * 3);
    std::vector<uint8_t> u(f.size());
    box_downsample_rgb(src.pixels.data(), 11, 9, s, f.data());
    box_downsample_rgb8(src.pixels.data(), 11, 9, s, ow, oh, u.data());
    for (int y = 0; y < oh; ++y)
      for (int x = 0; x < ow; ++x)
        for (int c = 0; c < 3; ++c) {
          int sum = 0;
          for (int j = 0; j < s; ++j)
            for (int i = 0; i < s; ++i) sum += src.pixels[(size_t(y * s + j) * 11 + size_t(x * s + i)) * 3 + size_t(c)];
          const size_t o = (size_t(y) * size_t(ow) + size_t(x)) * 3 + size_t(c);
          CHECK(f[o] == doctest::Approx(sum / (255.0 * s * s)).epsilon(1e-6));
          CHECK(int(u[o]) == (sum + s * s / 2) / (s * s));
        }
  }
  const uint8_t column[9] = {10, 20, 30, 200, 201, 202, 7, 8, 9};  // 1 x 3 RGB
  uint8_t one[3];
  box_downsample_rgb8(column, 1, 3, 2, 1, 1, one);
  // Rows 0 and 1, column 0 twice: (2 (10 + 200) + 2) / 4.
  CHECK(int(one[0]) == (2 * (10 + 200) + 2) / 4);
  CHECK(int(one[2]) == (2 * (30 + 202) + 2) / 4);
}

TEST_CASE("image_from_float_rgb clamps and rounds") {
  const float in[6] = {-1.0f, 0.0f, 0.5f, 1.0f, 2.0f, std::nanf("")};
  const Image8 img = image_from_float_rgb(in, 2, 1);
  REQUIRE(img.pixels.size() == 6);
  CHECK(img.pixels[0] == 0);
  CHECK(img.pixels[1] == 0);
  CHECK(img.pixels[2] == 128);  // 127.5 rounds up
  CHECK(img.pixels[3] == 255);
  CHECK(img.pixels[4] == 255);
  CHECK(img.pixels[5] == 0);
}

}  // namespace
}  // namespace gs::io

namespace gs::io {
namespace {

TEST_CASE("decode as stored keeps alpha, read_image_info, JPEG encode round trip") {
  test::TempDir dir;
  const Image8 rgba = random_image(7, 5, 4, 3), rgb = random_image(7, 5, 3, 4), grey = random_image(7, 5, 1, 5);
  Image8 grey_alpha = rgba;  // stb writes 2-channel PNGs; read back as stored they are RGBA
  grey_alpha.channels = 2;
  grey_alpha.pixels.resize(7 * 5 * 2);
  REQUIRE(write_png(dir / "rgba.png", rgba).ok());
  REQUIRE(write_png(dir / "rgb.png", rgb).ok());
  REQUIRE(write_png(dir / "grey.png", grey).ok());
  REQUIRE(write_png(dir / "ga.png", grey_alpha).ok());
  auto a = read_image(dir / "rgba.png", kChannelsAsStored);
  REQUIRE(a.ok());
  CHECK(a->channels == 4);
  CHECK(a->pixels == rgba.pixels);
  auto b = read_image(dir / "rgb.png", kChannelsAsStored);
  REQUIRE(b.ok());
  CHECK(b->channels == 3);
  CHECK(b->pixels == rgb.pixels);
  auto g = read_image(dir / "grey.png", kChannelsAsStored);
  REQUIRE(g.ok());
  CHECK(g->channels == 3);  // grey is expanded to RGB
  CHECK(g->pixels[0] == grey.pixels[0]);
  CHECK(g->pixels[2] == grey.pixels[0]);
  auto ga = read_image(dir / "ga.png", kChannelsAsStored);
  REQUIRE(ga.ok());
  CHECK(ga->channels == 4);
  CHECK(ga->pixels[3] == grey_alpha.pixels[1]);
  for (const auto& [name, alpha] : {std::pair<const char*, bool>{"rgba.png", true}, {"rgb.png", false}, {"grey.png", false}, {"ga.png", true}}) {
    auto info = read_image_info(dir / name);
    REQUIRE(info.ok());
    CHECK(info->width == 7);
    CHECK(info->height == 5);
    CHECK(info->has_alpha == alpha);
  }
  check_error(read_image_info(dir / "missing.png").status(), {dir / "missing.png"});
  // JPEG: smooth images come back within a few levels; RGBA and bad qualities are refused.
  const Image8 smooth = gradient_image(32, 24);
  REQUIRE(write_jpeg(dir / "s.jpg", smooth, 95).ok());
  auto j = read_image(dir / "s.jpg", kChannelsAsStored);
  REQUIRE(j.ok());
  CHECK(j->channels == 3);
  double err = 0;
  for (size_t i = 0; i < smooth.pixels.size(); ++i) err += std::abs(int(j->pixels[i]) - int(smooth.pixels[i]));
  CHECK(err / double(smooth.pixels.size()) < 2.0);
  check_error(encode_jpeg(rgba).status(), {"encode_jpeg", "1 or 3 channels"});
  check_error(encode_jpeg(rgb, 0).status(), {"quality 0"});
}

}  // namespace
}  // namespace gs::io
