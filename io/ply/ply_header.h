// SPDX-License-Identifier: MIT
// The one PLY header reader of gs_io (elements of fixed-size scalar properties, binary little-endian
// or, for the point-cloud reader, ascii): the 3DGS PLY reader, PlayCanvas's compressed.ply and the
// point-cloud PLY reader (dataset/point_ply.cpp) read through it, and the format dispatcher uses it
// to tell the two kinds of .ply apart. Private to gs_io.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/status.h"

namespace gs::io::detail {

// A scalar property's type, for readers that take any of them (the point-cloud reader).
enum class PlyScalar : uint8_t { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

struct PlyProperty {
  std::string name;
  std::string type;     // canonical: int8 uint8 int16 uint16 int32 uint32 float32 float64, or "list"
  PlyScalar scalar = PlyScalar::kUint8;  // the same as an enum (meaningless for a list)
  std::string spelled;  // the type as the header writes it ("float", "uchar", "list", ...), for messages
  size_t bytes = 0;     // size of one value (0 for a list)
  size_t offset = 0;    // from the start of its element's record (meaningless after a list)
};

struct PlyElement {
  std::string name;
  uint64_t count = 0;
  size_t record_bytes = 0;  // sum of its properties' sizes (records of variable size if has_list)
  bool has_list = false;
  std::vector<PlyProperty> properties;
  const PlyProperty* find(const std::string& property) const;
};

struct PlyHeader {
  size_t bytes = 0;  // header length including the "end_header" line and its "\n" (or "\r\n")
  bool ascii = false;  // "format ascii 1.0" (only with accept_ascii); else binary_little_endian
  std::vector<PlyElement> elements;
  const PlyElement* find(const std::string& element) const;
  // What the elements' records occupy after the header; elements with a list property must have
  // no records (callers refuse them otherwise).
  uint64_t body_bytes() const;
};

// Parses the header; refuses other formats than binary_little_endian 1.0 (and ascii 1.0 when
// accept_ascii), unknown types, duplicate elements or properties, and element counts above
// max_count, naming `source` and the header line. Does not look at the body. A list property is
// recorded (type "list"); what to do with it is the caller's business.
Status parse_ply_header(const uint8_t* data, size_t size, const std::string& source, uint64_t max_count, PlyHeader* out,
                        bool accept_ascii = false);

}  // namespace gs::io::detail
