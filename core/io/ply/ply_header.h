// SPDX-License-Identifier: MIT
// A general binary little-endian PLY header (elements of fixed-size scalar properties), for the
// PLY layouts other than the 3DGS one: PlayCanvas's compressed.ply reads through it, and the
// format dispatcher uses it to tell the two kinds of .ply apart. Private to gs_io.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/status.h"

namespace gs::io::detail {

struct PlyProperty {
  std::string name;
  std::string type;     // canonical: int8 uint8 int16 uint16 int32 uint32 float32 float64, or "list"
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
  size_t bytes = 0;  // header length including "end_header\n"
  std::vector<PlyElement> elements;
  const PlyElement* find(const std::string& element) const;
  // What the elements' records occupy after the header; elements with a list property must have
  // no records (callers refuse them otherwise).
  uint64_t body_bytes() const;
};

// Parses the header; refuses other formats than binary_little_endian 1.0, unknown types, and
// element counts above max_count, naming `source` and the header line. Does not look at the body.
// A list property is recorded (type "list"); what to do with it is the caller's business.
Status parse_ply_header(const uint8_t* data, size_t size, const std::string& source, uint64_t max_count, PlyHeader* out);

}  // namespace gs::io::detail
