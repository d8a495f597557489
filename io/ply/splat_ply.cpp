// SPDX-License-Identifier: MIT
// 3DGS checkpoint PLY (binary little-endian, float32 vertex properties), read and written.
// The header is read by the general PLY header reader (ply_header.h) and every count checked
// against the file size before the cloud is allocated; f_rest is converted between the file's channel-major order and GaussianCloud::sh.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>

#include "../io_util.h"
#include "../splat/splat_common.h"
#include "ply_header.h"
#include "gs/io/ply.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

constexpr uint64_t kMaxGaussians = 100'000'000;
// Inverse of sh_coeff_count - 1 for the f_rest counts the layout allows (3 * (K - 1)).
int degree_from_rest(size_t n) { return n == 0 ? 0 : n == 9 ? 1 : n == 24 ? 2 : n == 45 ? 3 : -1; }

struct Header {
  size_t bytes = 0;                    // header length including "end_header\n"
  uint64_t count = 0;                  // vertices
  std::map<std::string, size_t> prop;  // name -> float index within a vertex
  size_t floats = 0;                   // floats per vertex
  size_t rest = 0;                     // f_rest count
};

Status parse_header(const uint8_t* data, size_t size, const std::string& src, Header* h) {
  detail::PlyHeader ply;
  GS_RETURN_IF_ERROR(detail::parse_ply_header(data, size, src, kMaxGaussians, &ply));
  h->bytes = ply.bytes;
  const detail::PlyElement* vertex = ply.find("vertex");
  if (!vertex) return parse_error(src + ": PLY header has no 'vertex' element");
  for (const detail::PlyElement& e : ply.elements)
    if (&e != vertex && e.count != 0)
      return unsupported(src + ": element '" + e.name + "' with " + std::to_string(e.count) +
                         " entries (only vertices are read)");
  h->count = vertex->count;
  for (const detail::PlyProperty& p : vertex->properties) {
    if (p.type == "list") return unsupported(src + ": list property '" + p.name + "' in the vertex element");
    if (p.type != "float32")
      return unsupported(src + ": vertex property '" + p.name + "' has type " + p.spelled + " (only float is supported)");
    h->prop.emplace(p.name, h->floats++);
  }

  for (const char* name : {"x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
                           "rot_0", "rot_1", "rot_2", "rot_3"})
    if (!h->prop.count(name)) return parse_error(src + ": PLY vertex has no '" + name + "' property (not a 3DGS file?)");
  for (const auto& kv : h->prop) {
    if (kv.first.compare(0, 7, "f_rest_") != 0) continue;
    ++h->rest;
  }
  for (size_t j = 0; j < h->rest; ++j)
    if (!h->prop.count("f_rest_" + std::to_string(j)))
      return parse_error(src + ": f_rest properties are not numbered 0.." + std::to_string(h->rest - 1));
  if (degree_from_rest(h->rest) < 0)
    return unsupported(src + ": " + std::to_string(h->rest) + " f_rest properties; expected 0, 9, 24 or 45 (SH degree 0..3)");

  const uint64_t stride = h->floats * 4;
  if (h->count > (size - h->bytes) / stride)
    return parse_error(src + ": truncated: " + std::to_string(h->count) + " vertices of " + std::to_string(stride) +
                       " bytes need " + std::to_string(h->count * stride) + " bytes after the header, the file has " +
                       std::to_string(size - h->bytes));
  // More data than the header declares: a vertex count that is too low would silently drop the
  // rest of the scene, so it is an error too.
  if (h->count * stride != size - h->bytes)
    return parse_error(src + ": the header declares " + std::to_string(h->count) + " vertices of " + std::to_string(stride) +
                       " bytes (" + std::to_string(h->count * stride) + " bytes), but " + std::to_string(size - h->bytes) +
                       " bytes follow it: " + std::to_string(size - h->bytes - h->count * stride) +
                       " bytes would be ignored (is the vertex count wrong?)");
  return Status::Ok();
}

Expected<GaussianCloud> parse(const uint8_t* data, size_t size, const std::string& src) {
  Header h;
  GS_RETURN_IF_ERROR(parse_header(data, size, src, &h));
  GaussianCloud cloud;
  cloud.sh_degree = degree_from_rest(h.rest);
  cloud.resize(size_t(h.count));
  const size_t K = size_t(sh_coeff_count(cloud.sh_degree)), R = K - 1;
  auto idx = [&](const std::string& name) { return h.prop.at(name); };
  size_t pos[3], dc[3], scale[3], rot[4], opacity = idx("opacity");
  for (int c = 0; c < 3; ++c) {
    pos[c] = idx(std::string(1, char('x' + c)));
    dc[c] = idx("f_dc_" + std::to_string(c));
    scale[c] = idx("scale_" + std::to_string(c));
  }
  for (int c = 0; c < 4; ++c) rot[c] = idx("rot_" + std::to_string(c));
  std::vector<size_t> rest(h.rest);
  for (size_t j = 0; j < h.rest; ++j) rest[j] = idx("f_rest_" + std::to_string(j));

  const size_t stride = h.floats * 4;
  for (size_t n = 0; n < size_t(h.count); ++n) {
    const uint8_t* v = data + h.bytes + n * stride;
    auto f = [&](size_t i) { return detail::load_f32(v + 4 * i); };
    for (int c = 0; c < 3; ++c) {
      cloud.means[3 * n + size_t(c)] = f(pos[c]);
      cloud.log_scales[3 * n + size_t(c)] = f(scale[c]);
      cloud.sh[n * K * 3 + size_t(c)] = f(dc[c]);
    }
    for (int c = 0; c < 4; ++c) cloud.quats[4 * n + size_t(c)] = f(rot[c]);
    cloud.opacity_logits[n] = f(opacity);
    // File: f_rest_{c * R + (k - 1)} (channel-major); cloud: sh[n, k, c].
    for (size_t c = 0; c < 3; ++c)
      for (size_t k = 1; k < K; ++k) cloud.sh[(n * K + k) * 3 + c] = f(rest[c * R + (k - 1)]);
  }
  GS_RETURN_IF_ERROR(detail::check_cloud_finite(cloud, src));
  return cloud;
}

bool cloud_is_consistent(const GaussianCloud& c) {
  if (c.sh_degree < 0 || c.sh_degree > 3) return false;
  const size_t n = c.size();
  return n <= kMaxGaussians && c.means.size() == 3 * n && c.log_scales.size() == 3 * n && c.quats.size() == 4 * n &&
         c.sh.size() == n * size_t(sh_coeff_count(c.sh_degree)) * 3;
}

}  // namespace

Expected<GaussianCloud> parse_splat_ply(const uint8_t* data, size_t size, const std::string& source) {
  return detail::guarded(source, [&]() { return parse(data, size, source); });
}

Expected<GaussianCloud> read_splat_ply(const std::string& path) {
  return detail::read_and_parse(path, parse);
}

std::vector<uint8_t> encode_splat_ply(const GaussianCloud& cloud) {
  if (!cloud_is_consistent(cloud)) return {};
  try {
    const size_t n = cloud.size(), K = size_t(sh_coeff_count(cloud.sh_degree)), R = K - 1;
    std::string head = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) + "\n";
    std::vector<std::string> names = {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"};
    for (size_t j = 0; j < 3 * R; ++j) names.push_back("f_rest_" + std::to_string(j));
    for (const char* s : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"}) names.push_back(s);
    for (const std::string& s : names) head += "property float " + s + "\n";
    head += "end_header\n";

    std::vector<uint8_t> out(head.begin(), head.end());
    out.reserve(out.size() + n * names.size() * 4);
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) detail::append_f32(out, cloud.means[3 * i + size_t(c)]);
      for (int c = 0; c < 3; ++c) detail::append_f32(out, 0.0f);  // normals: unused by 3DGS, kept for viewers
      for (size_t c = 0; c < 3; ++c) detail::append_f32(out, cloud.sh[i * K * 3 + c]);
      for (size_t c = 0; c < 3; ++c)
        for (size_t k = 1; k < K; ++k) detail::append_f32(out, cloud.sh[(i * K + k) * 3 + c]);
      detail::append_f32(out, cloud.opacity_logits[i]);
      for (int c = 0; c < 3; ++c) detail::append_f32(out, cloud.log_scales[3 * i + size_t(c)]);
      for (int c = 0; c < 4; ++c) detail::append_f32(out, cloud.quats[4 * i + size_t(c)]);
    }
    return out;
  } catch (...) {
    return {};
  }
}

Status write_splat_ply(const std::string& path, const GaussianCloud& cloud) {
  if (!cloud_is_consistent(cloud))
    return invalid_argument(path + ": GaussianCloud arrays do not match its size and SH degree");
  return detail::guarded(path, [&]() -> Status {
    const std::vector<uint8_t> bytes = encode_splat_ply(cloud);
    if (bytes.empty()) return Status(StatusCode::kInternal, path + ": PLY encoding failed (out of memory?)");
    return platform::write_file_atomic(path, bytes.data(), bytes.size());
  });
}

}  // namespace gs::io
