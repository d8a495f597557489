// SPDX-License-Identifier: MIT
// The PLY header reader of ply_header.h: element and property lines, the PLY type names and their
// aliases, and overflow-safe counts.
#include "ply_header.h"

#include <algorithm>
#include <sstream>

namespace gs::io::detail {
namespace {

constexpr size_t kMaxHeaderBytes = 1 << 16;

// Canonical name, enum and size of a PLY scalar type (both spellings of the PLY spec); bytes 0 if
// unknown.
void scalar_type(const std::string& t, std::string* canonical, PlyScalar* scalar, size_t* bytes) {
  static const struct {
    const char* a;
    const char* b;
    PlyScalar scalar;
    size_t bytes;
  } kTypes[] = {{"char", "int8", PlyScalar::kInt8, 1},       {"uchar", "uint8", PlyScalar::kUint8, 1},
                {"short", "int16", PlyScalar::kInt16, 2},    {"ushort", "uint16", PlyScalar::kUint16, 2},
                {"int", "int32", PlyScalar::kInt32, 4},      {"uint", "uint32", PlyScalar::kUint32, 4},
                {"float", "float32", PlyScalar::kFloat32, 4}, {"double", "float64", PlyScalar::kFloat64, 8}};
  for (const auto& k : kTypes)
    if (t == k.a || t == k.b) {
      *canonical = k.b;
      *scalar = k.scalar;
      *bytes = k.bytes;
      return;
    }
  *bytes = 0;
}

}  // namespace

const PlyProperty* PlyElement::find(const std::string& property) const {
  for (const PlyProperty& p : properties)
    if (p.name == property) return &p;
  return nullptr;
}

const PlyElement* PlyHeader::find(const std::string& element) const {
  for (const PlyElement& e : elements)
    if (e.name == element) return &e;
  return nullptr;
}

uint64_t PlyHeader::body_bytes() const {
  uint64_t total = 0;
  for (const PlyElement& e : elements) total += e.count * e.record_bytes;  // counts and records are capped: no overflow
  return total;
}

Status parse_ply_header(const uint8_t* data, size_t size, const std::string& src, uint64_t max_count, PlyHeader* out,
                        bool accept_ascii) {
  const std::string head(reinterpret_cast<const char*>(data), std::min(size, kMaxHeaderBytes));
  if (head.compare(0, 4, "ply\n") != 0 && head.compare(0, 5, "ply\r\n") != 0)
    return parse_error(src + ": not a PLY file (no 'ply' line at the start)");
  // The header ends with the line "end_header", which (like "ply") may end in "\r\n".
  size_t end = head.find("end_header");
  while (end != std::string::npos && head.compare(end + 10, 1, "\n") != 0 && head.compare(end + 10, 2, "\r\n") != 0)
    end = head.find("end_header", end + 10);
  if (end == std::string::npos) return parse_error(src + ": PLY header has no 'end_header' line (truncated?)");
  out->bytes = end + (head[end + 10] == '\r' ? 12 : 11);
  out->ascii = false;
  out->elements.clear();

  std::istringstream lines(head.substr(0, end));
  std::string line;
  bool format_ok = false;
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
      if (fmt == "ascii" && accept_ascii) out->ascii = true;
      else if (fmt != "binary_little_endian")
        return unsupported(at + "format '" + fmt + (accept_ascii ? "' (ascii or binary_little_endian)" : "' (only binary_little_endian)"));
      if (ver != "1.0") return unsupported(at + "format version '" + ver + "'");
      format_ok = true;
    } else if (kw == "element") {
      PlyElement e;
      std::string count_tok;
      ls >> e.name >> count_tok;
      if (e.name.empty() || count_tok.empty()) return parse_error(at + "element without a name and count");
      for (char c : count_tok) {
        if (c < '0' || c > '9' || e.count > max_count) return parse_error(at + "bad element count '" + count_tok + "'");
        e.count = e.count * 10 + uint64_t(c - '0');
      }
      if (e.count > max_count)
        return unsupported(at + "element '" + e.name + "' has " + count_tok + " entries, more than the " +
                           std::to_string(max_count) + " allowed");
      for (const PlyElement& other : out->elements)
        if (other.name == e.name) return parse_error(at + "second '" + e.name + "' element");
      out->elements.push_back(std::move(e));
    } else if (kw == "property") {
      if (out->elements.empty()) return parse_error(at + "property before any element");
      PlyElement& e = out->elements.back();
      std::string type, name;
      ls >> type;
      PlyProperty p;
      p.spelled = type;
      if (type == "list") {  // list <count type> <item type> <name>: records of variable size
        std::string count_type, item_type, canonical;
        PlyScalar scalar;
        size_t count_bytes = 0, item_bytes = 0;
        ls >> count_type >> item_type >> name;
        scalar_type(count_type, &canonical, &scalar, &count_bytes);
        scalar_type(item_type, &canonical, &scalar, &item_bytes);
        if (count_bytes == 0 || item_bytes == 0)
          return parse_error(at + "list property with unknown types '" + count_type + "' '" + item_type + "'");
        p.type = "list";
        e.has_list = true;
      } else {
        ls >> name;
        scalar_type(type, &p.type, &p.scalar, &p.bytes);
        if (p.bytes == 0) return parse_error(at + "unknown property type '" + type + "'");
      }
      p.name = name;
      if (name.empty()) return parse_error(at + "property without a name");
      if (e.find(name)) return parse_error(at + "duplicate property '" + name + "' in element '" + e.name + "'");
      if (e.properties.size() >= 1024) return unsupported(at + "more than 1024 properties in element '" + e.name + "'");
      p.offset = e.record_bytes;
      e.record_bytes += p.bytes;
      e.properties.push_back(std::move(p));
    } else {
      return parse_error(at + "unexpected keyword '" + kw + "'");
    }
  }
  if (!format_ok) return parse_error(src + ": PLY header has no 'format' line");
  return Status::Ok();
}

}  // namespace gs::io::detail
