// SPDX-License-Identifier: MIT
// 3DGS PLY tests: round trips at SH degree 0 and 3, the channel-major f_rest layout checked on a
// hand-written file, and malformed headers/bodies that must be refused before allocation.
#include <cstring>
#include <random>

#include "gs/io/ply.h"
#include "io_test_util.h"

namespace gs::io {
namespace {

using test::check_error;

GaussianCloud random_cloud(int degree, size_t n, uint32_t seed) {
  GaussianCloud c;
  c.sh_degree = degree;
  c.resize(n);
  std::mt19937 rng(seed);
  std::normal_distribution<float> d;
  for (auto* v : {&c.means, &c.log_scales, &c.quats, &c.opacity_logits, &c.sh})
    for (float& x : *v) x = d(rng);
  return c;
}

void check_same(const GaussianCloud& a, const GaussianCloud& b) {
  CHECK(a.sh_degree == b.sh_degree);
  CHECK(a.means == b.means);
  CHECK(a.log_scales == b.log_scales);
  CHECK(a.quats == b.quats);
  CHECK(a.opacity_logits == b.opacity_logits);
  CHECK(a.sh == b.sh);
}

void append_f32(std::string& s, float f) { s.append(reinterpret_cast<const char*>(&f), 4); }  // little-endian hosts

std::string header(const std::string& props, uint64_t n, const std::string& extra = "") {
  return "ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex " + std::to_string(n) + "\n" + props + extra +
         "end_header\n";
}
std::string float_props(const std::vector<std::string>& names) {
  std::string s;
  for (const std::string& n : names) s += "property float " + n + "\n";
  return s;
}
const std::vector<std::string> kBase = {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
                                        "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"};

Expected<GaussianCloud> parse(const std::string& bytes) {
  return parse_splat_ply(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), "t.ply");
}

TEST_CASE("PLY round trip at SH degree 0 and 3") {
  for (int degree : {0, 3}) {
    const GaussianCloud c = random_cloud(degree, 17, uint32_t(degree + 1));
    const std::vector<uint8_t> bytes = encode_splat_ply(c);
    const std::string head(bytes.begin(), bytes.begin() + 200);
    CHECK(test::contains(head, "property float nx\n"));
    auto back = parse_splat_ply(bytes.data(), bytes.size(), "rt.ply");
    REQUIRE_MESSAGE(back.ok(), back.status().to_string());
    check_same(c, *back);
  }
  test::TempDir dir;
  const GaussianCloud c = random_cloud(2, 5, 3);
  REQUIRE(write_splat_ply(dir / "c.ply", c).ok());
  auto back = read_splat_ply(dir / "c.ply");
  REQUIRE(back.ok());
  check_same(c, *back);
  GaussianCloud bad = c;
  bad.quats.pop_back();
  CHECK_FALSE(write_splat_ply(dir / "bad.ply", bad).ok());
  CHECK(encode_splat_ply(bad).empty());
}

TEST_CASE("PLY f_rest is channel-major in the file and properties may come in any order") {
  // Degree 1: K = 4, so 9 f_rest values: R1 R2 R3 G1 G2 G3 B1 B2 B3. An unknown float property is skipped.
  std::vector<std::string> names = {"rot_3", "f_rest_8", "opacity", "extra"};
  for (int j = 0; j < 8; ++j) names.push_back("f_rest_" + std::to_string(j));
  for (const std::string& b : kBase)
    if (b != "rot_3" && b != "opacity") names.push_back(b);
  std::string file = header(float_props(names), 2);
  for (int n = 0; n < 2; ++n)
    for (const std::string& name : names) {
      float v = -1;
      if (name.rfind("f_rest_", 0) == 0) v = 100.0f * float(n) + 10.0f + float(std::stoi(name.substr(7)));
      else if (name.rfind("f_dc_", 0) == 0) v = 100.0f * float(n) + float(std::stoi(name.substr(5)));
      else if (name == "opacity") v = 0.25f + float(n);
      else if (name == "rot_3") v = 3.0f;
      else if (name == "x") v = 7.0f;
      append_f32(file, v);
    }
  auto c = parse(file);
  REQUIRE_MESSAGE(c.ok(), c.status().to_string());
  REQUIRE(c->size() == 2);
  CHECK(c->sh_degree == 1);
  for (int n = 0; n < 2; ++n) {
    const float* sh = &c->sh[size_t(n) * 4 * 3];
    for (int ch = 0; ch < 3; ++ch) {
      CHECK(sh[ch] == 100.0f * float(n) + float(ch));  // k = 0: f_dc
      for (int k = 1; k < 4; ++k) CHECK(sh[k * 3 + ch] == 100.0f * float(n) + 10.0f + float(ch * 3 + (k - 1)));
    }
    CHECK(c->opacity_logits[size_t(n)] == 0.25f + float(n));
    CHECK(c->quats[size_t(n) * 4 + 3] == 3.0f);
    CHECK(c->means[size_t(n) * 3] == 7.0f);
  }
  // The writer puts them back in the standard order; reading that gives the same cloud.
  const auto bytes = encode_splat_ply(*c);
  auto again = parse_splat_ply(bytes.data(), bytes.size(), "again.ply");
  REQUIRE(again.ok());
  check_same(*c, *again);
}

TEST_CASE("malformed PLY files are refused with a reason") {
  const std::string props = float_props(kBase);
  std::string good = header(props, 3);
  for (int i = 0; i < 3 * 14; ++i) append_f32(good, float(i));
  REQUIRE(parse(good).ok());

  for (size_t cut : {size_t(0), size_t(3), size_t(40), good.size() - 3 * 56, good.size() - 1})
    check_error(parse(good.substr(0, cut)).status(), {"t.ply"});
  check_error(parse(good.substr(0, good.size() - 1)).status(), {"truncated", "3 vertices"});
  check_error(parse("plx" + good.substr(3)).status(), {"t.ply", "not a PLY"});
  check_error(parse("ply\nformat ascii 1.0\nelement vertex 0\n" + props + "end_header\n").status(), {"ascii"});
  check_error(parse(header(props, 3)).status(), {"truncated"});
  // A vertex count lower than the data: the third vertex would be dropped silently, so it is refused.
  std::string short_count = header(props, 2);
  short_count += good.substr(header(props, 3).size());
  check_error(parse(short_count).status(), {"t.ply", "declares 2 vertices", "56 bytes would be ignored"});

  std::string rest10;
  for (int j = 0; j < 10; ++j) rest10 += "property float f_rest_" + std::to_string(j) + "\n";
  const Status r10 = parse(header(props + rest10, 0)).status();
  check_error(r10, {"10 f_rest"});
  check_error(parse(header(props + "property float f_rest_1\n", 0)).status(), {"f_rest"});

  // Counts that would need gigabytes are refused from the header, before any allocation.
  check_error(parse(header(props, 200000000)).status(), {"200000000"});
  check_error(parse(header(props, 99999999)).status(), {"truncated", "99999999"});

  check_error(parse(header(props + "property double extra\n", 0)).status(), {"extra", "double"});
  check_error(parse(header(props + "property uchar red\n", 0)).status(), {"red", "uchar"});
  check_error(parse(header(float_props({"x", "y", "z"}), 0)).status(), {"f_dc_0"});
  check_error(parse(header(props, 0, "element face 2\nproperty list uchar int vertex_indices\n")).status(), {"face", "2"});
  CHECK(parse(header(props, 0, "element face 0\nproperty list uchar int vertex_indices\n")).ok());
  check_error(parse("ply\nformat binary_little_endian 1.0\nelement vertex 1\n" + props).status(), {"end_header"});

  std::mt19937 rng(3);
  for (int trial = 0; trial < 300; ++trial) {
    std::string bytes = good;
    for (int k = 0; k < 3; ++k) bytes[rng() % bytes.size()] = char(rng());
    auto r = parse(bytes);
    if (r.ok()) CHECK(r->means.size() == 3 * r->size());
  }
}

}  // namespace
}  // namespace gs::io
