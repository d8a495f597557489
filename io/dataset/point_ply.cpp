// SPDX-License-Identifier: MIT
// Point-cloud PLY files (nerfstudio's "ply_file_path": ascii or binary little-endian vertices with
// x, y, z and optional red, green, blue). The header is read by gs_io's one PLY header reader
// (ply/ply_header.h); unlike the 3DGS checkpoint reader (ply/splat_ply.cpp), any scalar property
// type is accepted and unknown properties are skipped. Every count is checked against the file's
// size before anything is allocated.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "../io_util.h"
#include "../ply/ply_header.h"
#include "gs/io/transforms.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

using detail::PlyScalar;

// Vertex counts above this are refused by the header reader; the body checks below refuse far
// smaller counts that the file's size cannot hold.
constexpr uint64_t kMaxVertices = uint64_t(1) << 40;

struct Property {
  std::string name;
  PlyScalar type;
  size_t offset;  // bytes into a binary vertex record
};

struct Header {
  bool ascii = false;
  size_t bytes = 0;  // header length including the "end_header" line
  uint64_t count = 0;
  std::vector<Property> props;
  size_t stride = 0;  // binary vertex record, bytes
};

// The vertex element of the header (read by detail::parse_ply_header): elements after it (faces,
// edges) are ignored, elements with entries before it are refused (their records would have to
// be skipped first), and its count is checked against the bytes after the header.
Status parse_header(const uint8_t* data, size_t size, const std::string& src, Header* h) {
  detail::PlyHeader ply;
  GS_RETURN_IF_ERROR(detail::parse_ply_header(data, size, src, kMaxVertices, &ply, /*accept_ascii=*/true));
  h->ascii = ply.ascii;
  h->bytes = ply.bytes;
  const detail::PlyElement* vertex = nullptr;
  for (const detail::PlyElement& e : ply.elements) {
    if (e.name == "vertex") {
      vertex = &e;
      break;
    }
    if (e.count != 0) return unsupported(src + ": PLY element '" + e.name + "' before the vertices (only the vertices are read)");
  }
  if (!vertex) return parse_error(src + ": PLY header has no 'vertex' element");
  h->count = vertex->count;
  for (const detail::PlyProperty& p : vertex->properties) {
    if (p.type == "list") return unsupported(src + ": PLY list property '" + p.name + "' in the vertex element");
    h->props.push_back({p.name, p.scalar, p.offset});
  }
  h->stride = vertex->record_bytes;
  const size_t body = size - h->bytes;
  if (h->ascii) {
    // Every value takes at least one character and one separator (the last may lack its separator).
    if (!h->props.empty() && h->count > (body + 1) / (2 * h->props.size()))
      return parse_error(src + ": truncated: " + std::to_string(h->count) + " vertices of " + std::to_string(h->props.size()) +
                         " values cannot fit in the " + std::to_string(body) + " bytes after the header");
  } else if (h->stride > 0 && h->count > body / h->stride) {
    return parse_error(src + ": truncated: " + std::to_string(h->count) + " vertices of " + std::to_string(h->stride) +
                       " bytes need " + std::to_string(h->count * h->stride) + " bytes after the header, the file has " +
                       std::to_string(body));
  }
  return Status::Ok();
}

double load_binary(const uint8_t* p, PlyScalar t) {
  switch (t) {
    case PlyScalar::kInt8: return double(int8_t(p[0]));
    case PlyScalar::kUint8: return double(p[0]);
    case PlyScalar::kInt16: return double(int16_t(detail::load_le(p, 2)));
    case PlyScalar::kUint16: return double(detail::load_le(p, 2));
    case PlyScalar::kInt32: return double(int32_t(detail::load_u32(p)));
    case PlyScalar::kUint32: return double(detail::load_u32(p));
    case PlyScalar::kFloat32: return double(detail::load_f32(p));
    case PlyScalar::kFloat64: return detail::load_f64(p);
  }
  return 0;
}

int index_of(const Header& h, const char* name) {
  for (size_t i = 0; i < h.props.size(); ++i)
    if (h.props[i].name == name) return int(i);
  return -1;
}

// A colour value as 8 bits: integers are levels (clamped to 0..255), floats are in [0, 1].
uint8_t colour_level(double v, PlyScalar t) {
  const double level = (t == PlyScalar::kFloat32 || t == PlyScalar::kFloat64) ? v * 255.0 : v;
  if (!(level > 0)) return 0;
  return level >= 255 ? 255 : uint8_t(std::lround(level));
}

Expected<PointCloud> parse(const uint8_t* data, size_t size, const std::string& src) {
  Header h;
  GS_RETURN_IF_ERROR(parse_header(data, size, src, &h));
  int pos[3], col[3];
  for (int c = 0; c < 3; ++c) {
    pos[c] = index_of(h, c == 0 ? "x" : c == 1 ? "y" : "z");
    col[c] = index_of(h, c == 0 ? "red" : c == 1 ? "green" : "blue");
    if (pos[c] < 0) return parse_error(src + ": PLY vertices have no '" + std::string(1, char('x' + c)) + "' property");
  }
  const bool has_colour = col[0] >= 0 && col[1] >= 0 && col[2] >= 0;
  PointCloud cloud;
  cloud.xyz.resize(size_t(h.count) * 3);
  cloud.rgb.assign(size_t(h.count) * 3, 128);
  std::vector<double> values(h.props.size());
  const char* text = reinterpret_cast<const char*>(data) + h.bytes;
  const char* text_end = reinterpret_cast<const char*>(data) + size;
  for (size_t n = 0; n < size_t(h.count); ++n) {
    if (h.ascii) {
      for (size_t k = 0; k < values.size(); ++k) {
        while (text < text_end && (*text == ' ' || *text == '\t' || *text == '\r' || *text == '\n')) ++text;
        // strtod needs a terminated token: copy it (tokens are short; the file is not terminated).
        const char* start = text;
        while (text < text_end && !(*text == ' ' || *text == '\t' || *text == '\r' || *text == '\n')) ++text;
        if (text - start > 64)
          return parse_error(src + ": vertex " + std::to_string(n) + ": value " + std::to_string(k) + " is over 64 characters long");
        const std::string token(start, size_t(text - start));
        char* stop = nullptr;
        values[k] = token.empty() ? 0 : std::strtod(token.c_str(), &stop);
        if (token.empty() || stop != token.c_str() + token.size())
          return parse_error(src + ": vertex " + std::to_string(n) + ": value " + std::to_string(k) + " ('" + token +
                             "') is not a number" + (token.empty() ? " (the file ends early)" : ""));
      }
    } else {
      const uint8_t* rec = data + h.bytes + n * h.stride;
      for (size_t k = 0; k < values.size(); ++k) values[k] = load_binary(rec + h.props[k].offset, h.props[k].type);
    }
    for (int c = 0; c < 3; ++c) {
      const double v = values[size_t(pos[c])];
      if (!std::isfinite(v) || std::abs(v) > 3e38)
        return parse_error(src + ": vertex " + std::to_string(n) + " has a non-finite or out-of-range coordinate");
      cloud.xyz[3 * n + size_t(c)] = float(v);
      if (has_colour) cloud.rgb[3 * n + size_t(c)] = colour_level(values[size_t(col[c])], h.props[size_t(col[c])].type);
    }
  }
  return cloud;
}

}  // namespace

Expected<PointCloud> parse_point_ply(const uint8_t* data, size_t size, const std::string& source) {
  return detail::guarded(source, [&]() -> Expected<PointCloud> {
    if (data == nullptr || size == 0) return parse_error(source + ": empty file, not a PLY point cloud");
    return parse(data, size, source);
  });
}

Expected<PointCloud> read_point_ply(const std::string& path) {
  return detail::guarded(path, [&]() -> Expected<PointCloud> {
    auto bytes = platform::read_file(path);
    if (!bytes.ok()) return bytes.status();
    return parse_point_ply(bytes->data(), bytes->size(), path);
  });
}

}  // namespace gs::io
