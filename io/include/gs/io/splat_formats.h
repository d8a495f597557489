// SPDX-License-Identifier: MIT
// The Gaussian splat file formats other tools exchange, read into and written from a
// gs::GaussianCloud, and one dispatcher over all of them (with the 3DGS PLY of gs/io/ply.h):
//
//   format                     bytes/splat        what it keeps (bounds: README "Splat file formats")
//   3DGS PLY (.ply)            248 at SH degree 3 everything, float32 (exact)
//   antimatter15 .splat        32                 float32 position and scale, 8-bit colour, alpha and
//                                                 rotation; SH degree 0 only
//   Niantic .spz (v2, v3, v4)  ~12-30, gzip/ZSTD  24-bit fixed-point position, 8-bit everything else,
//                                                 SH degree 0-3 at 5 (degree 1) / 4 (higher) bits
//   PlayCanvas compressed.ply  16 + SH bytes      per 256-splat chunk bounds, 11/10/11-bit position
//                                                 and log scale, 8-bit colour and alpha, smallest-
//                                                 three rotation, 8-bit SH
//
// Coordinates: hbgs's world frame is the 3DGS/COLMAP one (x right, y down, z forward, "RDF").
// .splat and compressed.ply store it as is; .spz stores RUB (OpenGL: y up, z back), so the writer
// flips y and z (and the quaternion and SH terms that change sign with them) and the reader flips
// back: a cloud comes back in the frame it was written in, as in Niantic's and PlayCanvas's tools.
//
// Every parser validates what it reads before allocating (counts against the bytes present, sizes
// capped, the gzip/ZSTD output capped by the size the header's count implies) and refuses non-finite
// values; messages name the source, the record or field, and what was expected. Writers refuse a
// cloud whose arrays do not match its size or hold NaN/Inf, and write atomically.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/gaussians.h"
#include "gs/status.h"

namespace gs::io {

// ---- antimatter15 .splat: 32 bytes per splat, no header ----------------------------------------
// position float32 x3, scale float32 x3 (exp of the log scale), RGBA uint8 x4 (colour
// 0.5 + SH_C0 * dc and sigmoid(opacity logit), clamped and rounded), rotation uint8 x4 (the
// normalised quaternion w, x, y, z as round(q * 128 + 128), clamped). Higher SH bands are dropped.
Expected<GaussianCloud> parse_antimatter_splat(const uint8_t* data, size_t size, const std::string& source);
Expected<GaussianCloud> read_antimatter_splat(const std::string& path);
Expected<std::vector<uint8_t>> encode_antimatter_splat(const GaussianCloud& cloud);
Status write_antimatter_splat(const std::string& path, const GaussianCloud& cloud);

// ---- Niantic .spz (versions 2, 3: one gzip stream, zlib; 4: ZSTD streams, libzstd) -------------
struct SpzWriteOptions {
  // 4: one ZSTD frame per attribute, the current version (Niantic's library and splat-transform
  // write it by default); 3: one gzip stream, for readers older than version 4. Both hold the
  // same bytes (smallest-three rotations, 4 bytes) and so the same splats; sizes measured equal on
  // a trained export, 4 % apart on random SH (README "Splat file formats"). 2: x, y, z rotations
  // with w >= 0 (3 bytes), gzip.
  int version = 4;
  int sh1_bits = 5;       // precision kept for SH degree-1 coefficients (1..8; Niantic's default)
  int sh_rest_bits = 4;   // for degrees 2 and 3 (1..8)
};
Expected<GaussianCloud> parse_spz(const uint8_t* data, size_t size, const std::string& source);
Expected<GaussianCloud> read_spz(const std::string& path);
Expected<std::vector<uint8_t>> encode_spz(const GaussianCloud& cloud, const SpzWriteOptions& options = {});
Status write_spz(const std::string& path, const GaussianCloud& cloud, const SpzWriteOptions& options = {});
// Whether this build reads and writes a version: 2 and 3 need zlib, 4 needs libzstd (cross builds
// without the target libraries have neither); the spz functions fail with kUnsupported, saying
// which library is missing, for a version this build lacks.
bool spz_version_supported(int version);
// All three versions (zlib and libzstd both found).
bool spz_supported();

// ---- PlayCanvas compressed.ply -----------------------------------------------------------------
// Elements chunk (per 256 splats: float32 min/max of position, log scale and colour), vertex
// (uint32 packed_position 11/10/11, packed_rotation 2+10/10/10, packed_scale 11/10/11,
// packed_color 8/8/8/8) and, for SH degree 1-3, sh (uint8 f_rest_*, channel-major as in 3DGS).
// Chunks written before per-chunk colour bounds (12 chunk properties) are read too.
Expected<GaussianCloud> parse_compressed_ply(const uint8_t* data, size_t size, const std::string& source);
Expected<GaussianCloud> read_compressed_ply(const std::string& path);
// The writer orders the splats along a Morton curve so that each chunk covers a compact region
// (its bounds, and so the quantisation steps, stay small). `order`, when not null, receives for
// every written splat the index of the cloud's splat it holds (size N).
Expected<std::vector<uint8_t>> encode_compressed_ply(const GaussianCloud& cloud, std::vector<uint32_t>* order = nullptr);
Status write_compressed_ply(const std::string& path, const GaussianCloud& cloud);
// True when the bytes start with a PLY header that has PlayCanvas's chunk and packed vertex layout.
bool is_compressed_ply(const uint8_t* data, size_t size);

// ---- all formats -------------------------------------------------------------------------------
enum class SplatFormat { kPly, kCompressedPly, kAntimatterSplat, kSpz };
const char* splat_format_name(SplatFormat format);  // "3DGS PLY", "compressed.ply", ".splat", ".spz"
// The extensions write_gaussians understands, for messages: ".ply, .compressed.ply, .splat, .spz".
const char* supported_splat_extensions();

// Reads any of the formats. The content decides where a format has a magic number ("ply" opens
// both PLY kinds, their header tells them apart; gzip is .spz); a .splat (no magic) is known by
// its extension. Anything else is refused with the list of supported formats. `format`, when not
// null, receives the format read.
Expected<GaussianCloud> parse_gaussians(const uint8_t* data, size_t size, const std::string& source,
                                        SplatFormat* format = nullptr);
Expected<GaussianCloud> read_gaussians(const std::string& path, SplatFormat* format = nullptr);

// The format a path's extension names (".compressed.ply" before ".ply"; case-insensitive).
Expected<SplatFormat> splat_format_from_extension(const std::string& path);
// Options of the formats that have any (the others ignore them).
struct SplatWriteOptions {
  SpzWriteOptions spz;
};
Expected<std::vector<uint8_t>> encode_gaussians(const GaussianCloud& cloud, SplatFormat format,
                                                const SplatWriteOptions& options = {});
// Writes by the path's extension, atomically; an unknown extension is refused with the list.
Status write_gaussians(const std::string& path, const GaussianCloud& cloud, const SplatWriteOptions& options = {});

}  // namespace gs::io
