// SPDX-License-Identifier: MIT
// PlayCanvas's compressed.ply (SuperSplat, splat-transform, the PlayCanvas engine), read and
// written (gs/io/splat_formats.h). Splats come in chunks of 256; each chunk stores float32 bounds
//   min_x min_y min_z max_x max_y max_z, min_scale_x .. max_scale_z (log scales),
//   min_r min_g min_b max_r max_g max_b (colour 0.5 + SH_C0 * dc; absent in older files: then
//   the colour bytes are the colour itself)
// and every splat four uint32 in element vertex, each value a fraction t of its chunk's range,
// stored as round(t * (2^bits - 1)):
//   packed_position  x 11 bits (31-21), y 10 (20-11), z 11 (10-0)
//   packed_rotation  bits 31-30 the index (w, x, y, z order) of the largest-magnitude component of
//                    the unit quaternion, made positive and left out; the other three in index
//                    order, 10 bits each, as c / sqrt(2) + 0.5 (|c| <= 1/sqrt(2))
//   packed_scale     as the position, on the log scales
//   packed_color     r 31-24, g 23-16, b 15-8 (fractions of the colour range), alpha 7-0
// SH degree 1-3 adds element sh with uint8 f_rest_0..f_rest_{3(K-1)-1} (channel-major, as the 3DGS
// PLY), each floor((c / 8 + 0.5) * 256) clamped: 0 and 255 read as -4 and 4, the rest as the
// middle of their 1/32-wide step (PlayCanvas's reader).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "../io_util.h"
#include "../ply/ply_header.h"
#include "gs/io/splat_formats.h"
#include "gs/platform/file.h"
#include "splat_common.h"

namespace gs::io {
namespace {

constexpr size_t kChunkSplats = 256;
constexpr const char* kChunkProps[18] = {"min_x",       "min_y",       "min_z",       "max_x",       "max_y",
                                         "max_z",       "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x",
                                         "max_scale_y", "max_scale_z", "min_r",       "min_g",       "min_b",
                                         "max_r",       "max_g",       "max_b"};
constexpr size_t kChunkPropsWithoutColour = 12;
constexpr const char* kVertexProps[4] = {"packed_position", "packed_rotation", "packed_scale", "packed_color"};
// Log scales are bounded to this range in the chunk bounds (as PlayCanvas's writer does): e^-20
// and e^20 are far outside any scene, and the bound keeps degenerate inputs from wrecking a chunk.
constexpr float kLogScaleLimit = 20.0f;
using detail::kSqrtHalf;

float unorm(uint32_t code, int bits) { return float(code & ((1u << bits) - 1)) / float((1u << bits) - 1); }
float lerp(float a, float b, float t) { return a * (1.0f - t) + b * t; }

float sh_from_byte(uint8_t v) {
  const float t = v == 0 ? 0.0f : v == 255 ? 1.0f : (float(v) + 0.5f) / 256.0f;
  return (t - 0.5f) * 8.0f;
}

// Degree from the number of SH rest values per splat (3 (K - 1)); -1 when not 9, 24 or 45.
int degree_from_rest(size_t n) { return n == 9 ? 1 : n == 24 ? 2 : n == 45 ? 3 : -1; }

// The element layout this reader knows, checked against the header. `chunk`, `vertex`, `sh` point
// into the header; property offsets come from it.
struct Layout {
  const detail::PlyElement* chunk = nullptr;
  const detail::PlyElement* vertex = nullptr;
  const detail::PlyElement* sh = nullptr;
  bool chunk_colours = false;
  int sh_degree = 0;
};

Status check_layout(const detail::PlyHeader& h, size_t size, const std::string& src, Layout* l) {
  l->chunk = h.find("chunk");
  l->vertex = h.find("vertex");
  l->sh = h.find("sh");
  if (!l->chunk || !l->vertex)
    return parse_error(src + ": not a compressed.ply (needs elements 'chunk' and 'vertex')");
  for (const detail::PlyElement& e : h.elements)
    if (&e != l->chunk && &e != l->vertex && &e != l->sh && e.count != 0)
      return unsupported(src + ": element '" + e.name + "' with " + std::to_string(e.count) +
                         " entries is not part of the compressed.ply layout");
  const detail::PlyElement& chunk = *l->chunk;
  l->chunk_colours = chunk.properties.size() == 18;
  if (chunk.properties.size() != 18 && chunk.properties.size() != kChunkPropsWithoutColour)
    return unsupported(src + ": element 'chunk' has " + std::to_string(chunk.properties.size()) +
                       " properties; compressed.ply chunks have 12 or 18");
  for (size_t k = 0; k < chunk.properties.size(); ++k) {
    const detail::PlyProperty* p = chunk.find(kChunkProps[k]);
    if (!p) return parse_error(src + ": element 'chunk' has no property '" + kChunkProps[k] + "'");
    if (p->type != "float32")
      return unsupported(src + ": chunk property '" + p->name + "' is " + p->type + " (expected float)");
  }
  if (l->vertex->properties.size() != 4)
    return unsupported(src + ": element 'vertex' has " + std::to_string(l->vertex->properties.size()) +
                       " properties; compressed.ply vertices have packed_position, packed_rotation, packed_scale, "
                       "packed_color");
  for (const char* name : kVertexProps) {
    const detail::PlyProperty* p = l->vertex->find(name);
    if (!p) return parse_error(src + ": element 'vertex' has no property '" + name + "'");
    if (p->type != "uint32") return unsupported(src + ": vertex property '" + p->name + "' is " + p->type + " (expected uint)");
  }
  const uint64_t n = l->vertex->count;
  const uint64_t chunks = (n + kChunkSplats - 1) / kChunkSplats;
  if (chunk.count != chunks)
    return parse_error(src + ": " + std::to_string(n) + " vertices need " + std::to_string(chunks) +
                       " chunks of 256, the header declares " + std::to_string(chunk.count));
  l->sh_degree = 0;
  if (l->sh && (l->sh->count != 0 || !l->sh->properties.empty())) {
    const int degree = degree_from_rest(l->sh->properties.size());
    if (degree < 0)
      return unsupported(src + ": element 'sh' has " + std::to_string(l->sh->properties.size()) +
                         " properties; expected 9, 24 or 45 (SH degree 1 to 3)");
    for (size_t j = 0; j < l->sh->properties.size(); ++j) {
      const detail::PlyProperty* p = l->sh->find("f_rest_" + std::to_string(j));
      if (!p) return parse_error(src + ": element 'sh' has no property 'f_rest_" + std::to_string(j) + "'");
      if (p->type != "uint8") return unsupported(src + ": sh property '" + p->name + "' is " + p->type + " (expected uchar)");
    }
    if (l->sh->count != n)
      return parse_error(src + ": element 'sh' has " + std::to_string(l->sh->count) + " entries for " +
                         std::to_string(n) + " vertices");
    l->sh_degree = degree;
  }
  const uint64_t body = h.body_bytes();
  if (body > uint64_t(std::numeric_limits<size_t>::max()) || size - h.bytes < body)
    return parse_error(src + ": truncated: the header's elements need " + std::to_string(body) +
                       " bytes after the header, the file has " + std::to_string(size - h.bytes));
  if (size - h.bytes != body)
    return parse_error(src + ": the header's elements need " + std::to_string(body) + " bytes after the header, but " +
                       std::to_string(size - h.bytes) + " follow it (are the counts wrong?)");
  return detail::check_cloud_fits(n, l->sh_degree, src);
}

// Where an element's records start in the file (elements are stored in header order).
const uint8_t* element_data(const uint8_t* data, const detail::PlyHeader& h, const detail::PlyElement* e) {
  size_t at = h.bytes;
  for (const detail::PlyElement& other : h.elements) {
    if (&other == e) break;
    at += size_t(other.count * other.record_bytes);
  }
  return data + at;
}

Expected<GaussianCloud> parse_compressed_ply_unguarded(const uint8_t* data, size_t size, const std::string& src) {
  detail::PlyHeader h;
  GS_RETURN_IF_ERROR(detail::parse_ply_header(data, size, src, detail::kMaxSplats, &h));
  Layout l;
  GS_RETURN_IF_ERROR(check_layout(h, size, src, &l));

  // Chunk bounds, [chunks, 18] in kChunkProps order; all finite.
  const size_t chunks = size_t(l.chunk->count), n = size_t(l.vertex->count);
  const uint8_t* chunk_data = element_data(data, h, l.chunk);
  std::vector<float> bounds(chunks * 18, 0.0f);
  for (size_t c = 0; c < chunks; ++c)
    for (size_t k = 0; k < l.chunk->properties.size(); ++k) {
      const float v = detail::load_f32(chunk_data + c * l.chunk->record_bytes + l.chunk->find(kChunkProps[k])->offset);
      if (!std::isfinite(v))
        return parse_error(src + ": chunk " + std::to_string(c) + ": " + kChunkProps[k] + " is " + std::to_string(v));
      bounds[c * 18 + k] = v;
    }

  GaussianCloud cloud;
  cloud.sh_degree = l.sh_degree;
  cloud.resize(n);
  const size_t K = size_t(sh_coeff_count(l.sh_degree)), R = K - 1;
  const uint8_t* vertex_data = element_data(data, h, l.vertex);
  size_t offsets[4];
  for (int k = 0; k < 4; ++k) offsets[k] = l.vertex->find(kVertexProps[k])->offset;
  for (size_t i = 0; i < n; ++i) {
    const float* b = &bounds[(i / kChunkSplats) * 18];
    const uint8_t* v = vertex_data + i * l.vertex->record_bytes;
    const uint32_t position = detail::load_u32(v + offsets[0]), rotation = detail::load_u32(v + offsets[1]);
    const uint32_t scale = detail::load_u32(v + offsets[2]), colour = detail::load_u32(v + offsets[3]);
    const float tp[3] = {unorm(position >> 21, 11), unorm(position >> 11, 10), unorm(position, 11)};
    const float ts[3] = {unorm(scale >> 21, 11), unorm(scale >> 11, 10), unorm(scale, 11)};
    for (int c = 0; c < 3; ++c) {
      cloud.means[3 * i + size_t(c)] = lerp(b[c], b[3 + c], tp[c]);
      cloud.log_scales[3 * i + size_t(c)] = lerp(b[6 + c], b[9 + c], ts[c]);
      const float t = unorm(colour >> (24 - 8 * c), 8);
      const float rgb = l.chunk_colours ? lerp(b[12 + c], b[15 + c], t) : t;
      cloud.sh[i * K * 3 + size_t(c)] = float((double(rgb) - 0.5) / detail::kShC0);
    }
    cloud.opacity_logits[i] = detail::logit_from_alpha8(colour & 255u);
    const int largest = int(rotation >> 30);
    float q[4];
    double sum_sq = 0;
    for (int k = 0, field = 2; k < 4; ++k) {
      if (k == largest) continue;
      q[k] = float((double(unorm(rotation >> (10 * field), 10)) - 0.5) / kSqrtHalf);
      sum_sq += double(q[k]) * q[k];
      --field;
    }
    q[largest] = float(std::sqrt(std::max(0.0, 1.0 - sum_sq)));
    double unit[4];
    detail::normalized_quaternion(q, unit);  // the left-out component is >= 0.5: never zero
    for (int k = 0; k < 4; ++k) cloud.quats[4 * i + size_t(k)] = float(unit[k]);
  }
  if (R > 0) {
    const uint8_t* sh_data = element_data(data, h, l.sh);
    std::vector<size_t> sh_offsets(3 * R);
    for (size_t j = 0; j < 3 * R; ++j) sh_offsets[j] = l.sh->find("f_rest_" + std::to_string(j))->offset;
    for (size_t i = 0; i < n; ++i)
      for (size_t ch = 0; ch < 3; ++ch)
        for (size_t k = 1; k < K; ++k)  // file: f_rest_{ch * R + k - 1}; cloud: sh[i, k, ch]
          cloud.sh[(i * K + k) * 3 + ch] = sh_from_byte(sh_data[i * l.sh->record_bytes + sh_offsets[ch * R + k - 1]]);
  }
  GS_RETURN_IF_ERROR(detail::check_cloud_finite(cloud, src));
  return cloud;
}

// Splat indices along a Morton (Z-order) curve of their positions, 10 bits per axis over the
// cloud's bounding box, ties in index order.
std::vector<uint32_t> morton_order(const GaussianCloud& cloud) {
  const size_t n = cloud.size();
  float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
  for (size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      const float v = cloud.means[3 * i + size_t(c)];
      lo[c] = i == 0 ? v : std::min(lo[c], v);
      hi[c] = i == 0 ? v : std::max(hi[c], v);
    }
  auto spread = [](uint32_t x) {  // bit k of a 10-bit x goes to bit 3k
    uint32_t r = 0;
    for (int k = 0; k < 10; ++k) r |= ((x >> k) & 1u) << (3 * k);
    return r;
  };
  std::vector<uint32_t> codes(n);
  for (size_t i = 0; i < n; ++i) {
    uint32_t code = 0;
    for (int c = 0; c < 3; ++c) {
      const double extent = double(hi[c]) - double(lo[c]);
      const double t = extent > 0 ? (double(cloud.means[3 * i + size_t(c)]) - lo[c]) / extent : 0.0;
      code |= spread(detail::quantize_clamped(t * 1023.0, 1023)) << (2 - c);
    }
    codes[i] = code;
  }
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return codes[a] < codes[b]; });
  return order;
}

// round(t * (2^bits - 1)) of v's fraction of [lo, hi]; a range under 1e-5 stores 0 (reads as lo).
uint32_t pack_fraction(double v, float lo, float hi, int bits) {
  const double range = double(hi) - double(lo);
  if (range < 1e-5) return 0;
  return detail::quantize_clamped((v - lo) / range * double((1u << bits) - 1), (1u << bits) - 1);
}

Expected<std::vector<uint8_t>> encode(const GaussianCloud& cloud, std::vector<uint32_t>* order_out) {
  GS_RETURN_IF_ERROR(detail::check_cloud_for_writing(cloud, "compressed.ply"));
  const size_t n = cloud.size(), K = size_t(sh_coeff_count(cloud.sh_degree)), R = K - 1;
  const size_t chunks = (n + kChunkSplats - 1) / kChunkSplats;
  std::string head = "ply\nformat binary_little_endian 1.0\ncomment written by hbgs\nelement chunk " +
                     std::to_string(chunks) + "\n";
  for (const char* p : kChunkProps) head += std::string("property float ") + p + "\n";
  head += "element vertex " + std::to_string(n) + "\n";
  for (const char* p : kVertexProps) head += std::string("property uint ") + p + "\n";
  if (R > 0) {
    head += "element sh " + std::to_string(n) + "\n";
    for (size_t j = 0; j < 3 * R; ++j) head += "property uchar f_rest_" + std::to_string(j) + "\n";
  }
  head += "end_header\n";

  const std::vector<uint32_t> order = morton_order(cloud);
  std::vector<uint8_t> chunk_bytes, vertex_bytes, sh_bytes;
  chunk_bytes.reserve(chunks * 18 * 4);
  vertex_bytes.reserve(n * 16);
  sh_bytes.reserve(n * 3 * R);
  auto colour_of = [&](size_t i, int c) { return 0.5 + detail::kShC0 * double(cloud.sh[i * K * 3 + size_t(c)]); };
  for (size_t first = 0; first < n; first += kChunkSplats) {
    const size_t last = std::min(n, first + kChunkSplats);
    float b[18];  // kChunkProps order
    for (int c = 0; c < 3; ++c) {
      b[c] = b[6 + c] = b[12 + c] = std::numeric_limits<float>::max();
      b[3 + c] = b[9 + c] = b[15 + c] = std::numeric_limits<float>::lowest();
    }
    for (size_t j = first; j < last; ++j) {
      const size_t i = order[j];
      for (int c = 0; c < 3; ++c) {
        const float p = cloud.means[3 * i + size_t(c)], s = cloud.log_scales[3 * i + size_t(c)];
        const float rgb = float(colour_of(i, c));
        b[c] = std::min(b[c], p), b[3 + c] = std::max(b[3 + c], p);
        b[6 + c] = std::min(b[6 + c], s), b[9 + c] = std::max(b[9 + c], s);
        b[12 + c] = std::min(b[12 + c], rgb), b[15 + c] = std::max(b[15 + c], rgb);
      }
    }
    for (int k = 6; k < 12; ++k) b[k] = std::min(std::max(b[k], -kLogScaleLimit), kLogScaleLimit);
    for (float v : b) detail::append_f32(chunk_bytes, v);

    for (size_t j = first; j < last; ++j) {
      const size_t i = order[j];
      const float* mean = &cloud.means[3 * i];
      const float* log_scale = &cloud.log_scales[3 * i];
      const uint32_t position = pack_fraction(mean[0], b[0], b[3], 11) << 21 |
                                pack_fraction(mean[1], b[1], b[4], 10) << 11 | pack_fraction(mean[2], b[2], b[5], 11);
      const uint32_t scale = pack_fraction(log_scale[0], b[6], b[9], 11) << 21 |
                             pack_fraction(log_scale[1], b[7], b[10], 10) << 11 |
                             pack_fraction(log_scale[2], b[8], b[11], 11);
      uint32_t colour = detail::quantize_clamped(detail::sigmoid(cloud.opacity_logits[i]) * 255.0, 255);
      for (int c = 0; c < 3; ++c) colour |= pack_fraction(colour_of(i, c), b[12 + c], b[15 + c], 8) << (24 - 8 * c);
      double q[4];
      detail::normalized_quaternion(&cloud.quats[4 * i], q);  // non-zero: checked above
      int largest = 0;
      for (int k = 1; k < 4; ++k)
        if (std::fabs(q[k]) > std::fabs(q[largest])) largest = k;
      const double sign = q[largest] < 0 ? -1.0 : 1.0;  // -q is the same rotation: the left-out one >= 0
      uint32_t rotation = uint32_t(largest);
      for (int k = 0; k < 4; ++k)
        if (k != largest) rotation = rotation << 10 | detail::quantize_clamped((sign * q[k] * kSqrtHalf + 0.5) * 1023.0, 1023);
      for (uint32_t word : {position, rotation, scale, colour}) detail::append_u32(vertex_bytes, word);
      for (size_t ch = 0; ch < 3; ++ch)
        for (size_t k = 1; k < K; ++k) {
          const double v = std::floor((double(cloud.sh[(i * K + k) * 3 + ch]) / 8.0 + 0.5) * 256.0);
          sh_bytes.push_back(uint8_t(std::min(std::max(v, 0.0), 255.0)));
        }
    }
  }
  std::vector<uint8_t> out(head.begin(), head.end());
  out.reserve(out.size() + chunk_bytes.size() + vertex_bytes.size() + sh_bytes.size());
  out.insert(out.end(), chunk_bytes.begin(), chunk_bytes.end());
  out.insert(out.end(), vertex_bytes.begin(), vertex_bytes.end());
  out.insert(out.end(), sh_bytes.begin(), sh_bytes.end());
  if (order_out) *order_out = order;
  return out;
}

}  // namespace

Expected<GaussianCloud> parse_compressed_ply(const uint8_t* data, size_t size, const std::string& source) {
  return detail::guarded(source, [&]() { return parse_compressed_ply_unguarded(data, size, source); });
}

Expected<GaussianCloud> read_compressed_ply(const std::string& path) {
  return detail::read_and_parse(path, parse_compressed_ply_unguarded);
}

Expected<std::vector<uint8_t>> encode_compressed_ply(const GaussianCloud& cloud, std::vector<uint32_t>* order) {
  return detail::guarded("compressed.ply", [&]() { return encode(cloud, order); });
}

Status write_compressed_ply(const std::string& path, const GaussianCloud& cloud) {
  Expected<std::vector<uint8_t>> bytes = encode_compressed_ply(cloud);
  if (!bytes.ok()) return Status(bytes.status().code(), path + ": " + bytes.status().message());
  return platform::write_file_atomic(path, bytes->data(), bytes->size());
}

bool is_compressed_ply(const uint8_t* data, size_t size) {
  detail::PlyHeader h;
  if (!detail::parse_ply_header(data, size, "", detail::kMaxSplats, &h).ok()) return false;
  const detail::PlyElement* vertex = h.find("vertex");
  return h.find("chunk") && vertex && vertex->find("packed_position");
}

}  // namespace gs::io
