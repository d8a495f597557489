// SPDX-License-Identifier: MIT
// Point-cloud PLY files (nerfstudio's "ply_file_path": ascii or binary little-endian vertices with
// x, y, z and optional red, green, blue). Unlike the 3DGS checkpoint reader (ply/splat_ply.cpp),
// any scalar property type is accepted and unknown properties are skipped. Every count is checked
// against the file's size before anything is allocated.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "../io_util.h"
#include "gs/io/transforms.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

constexpr size_t kMaxHeaderBytes = 1 << 16;

enum class Type { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

bool type_from_name(const std::string& n, Type* t, size_t* bytes) {
  struct Row {
    const char* a;
    const char* b;
    Type t;
    size_t bytes;
  };
  static const Row kRows[] = {{"char", "int8", Type::kInt8, 1},       {"uchar", "uint8", Type::kUint8, 1},
                              {"short", "int16", Type::kInt16, 2},    {"ushort", "uint16", Type::kUint16, 2},
                              {"int", "int32", Type::kInt32, 4},      {"uint", "uint32", Type::kUint32, 4},
                              {"float", "float32", Type::kFloat32, 4}, {"double", "float64", Type::kFloat64, 8}};
  for (const Row& r : kRows)
    if (n == r.a || n == r.b) {
      *t = r.t, *bytes = r.bytes;
      return true;
    }
  return false;
}

struct Property {
  std::string name;
  Type type;
  size_t offset;  // bytes into a binary vertex record
};

struct Header {
  bool ascii = false;
  size_t bytes = 0;  // header length including "end_header\n"
  uint64_t count = 0;
  std::vector<Property> props;
  size_t stride = 0;  // binary vertex record, bytes
};

Status parse_header(const uint8_t* data, size_t size, const std::string& src, Header* h) {
  const std::string head(reinterpret_cast<const char*>(data), std::min(size, kMaxHeaderBytes));
  if (head.compare(0, 4, "ply\n") != 0 && head.compare(0, 5, "ply\r\n") != 0)
    return parse_error(src + ": not a PLY file (no 'ply' line at the start)");
  const size_t end = head.find("end_header");
  const size_t eol = end == std::string::npos ? std::string::npos : head.find('\n', end);
  if (eol == std::string::npos) return parse_error(src + ": PLY header has no 'end_header' line (truncated?)");
  h->bytes = eol + 1;
  std::istringstream lines(head.substr(0, end));
  std::string line;
  bool format_ok = false, in_vertex = false, vertex_seen = false;
  int line_no = 0;
  while (std::getline(lines, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    const std::string at = src + ": PLY header line " + std::to_string(line_no) + ": ";
    if (line_no == 1 || kw.empty() || kw == "comment" || kw == "obj_info") continue;
    if (kw == "format") {
      std::string fmt, ver;
      ls >> fmt >> ver;
      if (fmt == "ascii") h->ascii = true;
      else if (fmt != "binary_little_endian")
        return unsupported(at + "format '" + fmt + "' (ascii or binary_little_endian)");
      format_ok = true;
    } else if (kw == "element") {
      std::string name, count_tok;
      ls >> name >> count_tok;
      uint64_t n = 0;
      for (char c : count_tok) {
        if (c < '0' || c > '9' || n > (uint64_t(1) << 40)) return parse_error(at + "bad element count '" + count_tok + "'");
        n = n * 10 + uint64_t(c - '0');
      }
      if (count_tok.empty()) return parse_error(at + "element without a count");
      if (vertex_seen) {
        in_vertex = false;  // elements after the vertices (faces, edges) are not read
        continue;
      }
      if (name == "vertex") {
        in_vertex = vertex_seen = true;
        h->count = n;
      } else if (n != 0) {
        return unsupported(at + "element '" + name + "' before the vertices (only the vertices are read)");
      }
    } else if (kw == "property") {
      std::string type, name;
      ls >> type >> name;
      if (!in_vertex) continue;
      if (type == "list") return unsupported(at + "list property in the vertex element");
      Property p;
      size_t bytes = 0;
      if (!type_from_name(type, &p.type, &bytes)) return parse_error(at + "unknown property type '" + type + "'");
      for (const Property& q : h->props)
        if (q.name == name) return parse_error(at + "duplicate vertex property '" + name + "'");
      p.name = name;
      p.offset = h->stride;
      h->stride += bytes;
      h->props.push_back(p);
    } else {
      return parse_error(at + "unexpected keyword '" + kw + "'");
    }
  }
  if (!format_ok) return parse_error(src + ": PLY header has no 'format' line");
  if (!vertex_seen) return parse_error(src + ": PLY header has no 'vertex' element");
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

double load_binary(const uint8_t* p, Type t) {
  switch (t) {
    case Type::kInt8: return double(int8_t(p[0]));
    case Type::kUint8: return double(p[0]);
    case Type::kInt16: return double(int16_t(detail::load_le(p, 2)));
    case Type::kUint16: return double(detail::load_le(p, 2));
    case Type::kInt32: return double(int32_t(detail::load_u32(p)));
    case Type::kUint32: return double(detail::load_u32(p));
    case Type::kFloat32: return double(detail::load_f32(p));
    case Type::kFloat64: return detail::load_f64(p);
  }
  return 0;
}

int index_of(const Header& h, const char* name) {
  for (size_t i = 0; i < h.props.size(); ++i)
    if (h.props[i].name == name) return int(i);
  return -1;
}

// A colour value as 8 bits: integers are levels (clamped to 0..255), floats are in [0, 1].
uint8_t colour_level(double v, Type t) {
  const double level = (t == Type::kFloat32 || t == Type::kFloat64) ? v * 255.0 : v;
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
