// SPDX-License-Identifier: MIT
// Image decoding: PNG/JPEG bytes -> Image8 through stb_image, with the header validated
// (format, sides within kMaxImageSide) before any pixel memory is allocated.
#define STBI_NO_STDIO
#include <stb_image.h>

#include <algorithm>
#include <climits>
#include <cstring>
#include <utility>
#include <vector>

#include "../io_util.h"
#include "gs/io/image.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

bool looks_like_png(const uint8_t* d, size_t n) {
  static const uint8_t kSig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  return n >= 8 && std::memcmp(d, kSig, 8) == 0;
}
bool looks_like_jpeg(const uint8_t* d, size_t n) { return n >= 3 && d[0] == 0xff && d[1] == 0xd8 && d[2] == 0xff; }

// PNG sides straight from IHDR (big-endian at bytes 16..23). stb's own info call refuses
// very large PNGs with only "unknown image type", so we read them to say what was wrong.
bool png_sides(const uint8_t* d, size_t n, uint64_t* w, uint64_t* h) {
  if (n < 24 || std::memcmp(d + 12, "IHDR", 4) != 0) return false;
  *w = (uint64_t(d[16]) << 24) | (uint64_t(d[17]) << 16) | (uint64_t(d[18]) << 8) | d[19];
  *h = (uint64_t(d[20]) << 24) | (uint64_t(d[21]) << 16) | (uint64_t(d[22]) << 8) | d[23];
  return true;
}

// The JPEG tables stb would trust, checked segment by segment before stb sees the file (every
// finding below came from fuzz/fuzz_image):
// - Debian 12's stb_image builds each Huffman table into fixed arrays of 256 codes without checking
//   the table's declared code count, so a table declaring more (the 16 counts sum past 256) writes
//   past the array. Every DHT segment, also those between the scans of a progressive JPEG, is
//   checked.
// - A scan decoding with a Huffman table that no DHT defined, or dequantising with a quantisation
//   table that no DQT defined, makes stb read never-initialised table memory (a negative symbol
//   index; quantisation steps that vary from run to run, up to 16 bits, whose products with the DC
//   coefficient overflowed int). Each scan's components must have both defined before the scan.
Status check_jpeg_tables(const uint8_t* d, size_t n, const std::string& source) {
  bool defined[2][4] = {};  // [class: 0 DC, 1 AC][table id], by a DHT so far
  bool quant_defined[4] = {};  // by a DQT so far
  // The frame's components (the first SOF; stb refuses a second): id -> quantisation table.
  std::vector<std::pair<uint8_t, uint8_t>> frame_tables;
  bool have_frame = false;
  size_t p = 2;  // after SOI
  while (p + 4 <= n) {
    if (d[p] != 0xff) {  // entropy-coded data between markers
      ++p;
      continue;
    }
    const uint8_t m = d[p + 1];
    if (m == 0xff) {  // fill byte
      ++p;
      continue;
    }
    if (m == 0x00 || m == 0x01 || (m >= 0xd0 && m <= 0xd7)) {  // stuffed 0xff, TEM, RSTn: no length
      p += 2;
      continue;
    }
    if (m == 0xd9) break;  // EOI
    const size_t len = (size_t(d[p + 2]) << 8) | d[p + 3];
    if (len < 2) break;  // stb reports it
    // A truncated DHT is checked as far as it goes (stb builds its tables before it notices, reading
    // zeros past the end).
    if (m == 0xc4) {
      size_t q = p + 4;
      const size_t end = std::min(p + 2 + len, n);
      while (q < end) {
        size_t codes = 0;  // stb reads bytes past the end of the file as 0
        for (size_t i = q + 1; i <= q + 16 && i < n; ++i) codes += d[i];
        if (codes > 256)
          return parse_error(source + ": corrupt JPEG: a Huffman table (DHT at byte " + std::to_string(p) + ") declares " +
                             std::to_string(codes) + " codes, more than 256");
        if ((d[q] >> 4) <= 1 && (d[q] & 15) <= 3) defined[d[q] >> 4][d[q] & 15] = true;
        q += 17 + codes;
      }
    }
    // DQT: (precision << 4 | id) then 64 steps of 1 or 2 bytes, repeated. stb refuses other
    // precisions and ids, and reads steps cut off by the end of the file as 0 (defined, if odd).
    if (m == 0xdb) {
      size_t q = p + 4;
      const size_t end = std::min(p + 2 + len, n);
      while (q < end && (d[q] >> 4) <= 1) {
        if ((d[q] & 15) <= 3) quant_defined[d[q] & 15] = true;
        q += 1 + 64 * (size_t(d[q] >> 4) + 1);
      }
    }
    // SOF0-2 (what stb decodes): Nf components of (id, sampling, quantisation table).
    if ((m == 0xc0 || m == 0xc1 || m == 0xc2) && !have_frame && p + 10 <= n) {
      have_frame = true;
      const size_t nf = d[p + 9];
      for (size_t c = 0; c < nf && p + 12 + 3 * c < n; ++c) frame_tables.emplace_back(d[p + 10 + 3 * c], d[p + 12 + 3 * c]);
    }
    // A scan that decodes with a Huffman table no DHT defined makes stb read its never-initialised
    // table memory (found by fuzz/fuzz_image: a negative symbol index, varying from run to run).
    // DC scans (Ss = 0) that are not refinements (Ah = 0) use DC tables; scans with Se > 0 use AC tables.
    if (m == 0xda && p + 2 + len <= n && len >= 3) {
      const size_t ns = d[p + 4];
      if (len >= 6 + 2 * ns) {
        const uint8_t ss = d[p + 5 + 2 * ns], se = d[p + 6 + 2 * ns], ah = d[p + 7 + 2 * ns] >> 4;
        for (size_t c = 0; c < ns; ++c) {
          const uint8_t tables = d[p + 6 + 2 * c];
          const int dc = tables >> 4, ac = tables & 15;
          if ((ss == 0 && ah == 0 && (dc > 3 || !defined[0][dc])) || (se > 0 && (ac > 3 || !defined[1][ac])))
            return parse_error(source + ": corrupt JPEG: the scan at byte " + std::to_string(p) +
                               " uses a Huffman table that no DHT segment defines");
          // A component the frame does not have, or a table id over 3: stb refuses those itself.
          const uint8_t id = d[p + 5 + 2 * c];
          for (const auto& [frame_id, quant] : frame_tables)
            if (frame_id == id && quant <= 3 && !quant_defined[quant])
              return parse_error(source + ": corrupt JPEG: the scan at byte " + std::to_string(p) + " uses quantisation table " +
                                 std::to_string(quant) + ", which no DQT segment before it defines");
        }
      }
    }
    if (p + 2 + len > n) break;  // truncated: stb reports it
    p += 2 + len;
  }
  return Status::Ok();
}

// stb_image sizes its buffer for a PNG data chunk from the chunk's declared length before reading
// it, so a 2 KB file declaring a 1.8 GB IDAT made it allocate 1.8 GB (found by fuzz/fuzz_image).
// Every chunk must fit in the file.
// An empty IDAT chunk before any image data makes stb copy 0 bytes to its not yet allocated data
// buffer, memcpy(NULL, ..., 0), which is undefined (found by fuzz/fuzz_image); encoders do not write
// empty IDAT chunks, so such a file is refused.
Status check_png_chunks(const uint8_t* d, size_t n, const std::string& source) {
  size_t p = 8;  // after the signature
  bool image_data = false;
  while (p + 8 <= n) {
    const uint64_t len = (uint64_t(d[p]) << 24) | (uint64_t(d[p + 1]) << 16) | (uint64_t(d[p + 2]) << 8) | d[p + 3];
    const std::string type(reinterpret_cast<const char*>(d + p + 4), 4);
    if (len > n - p - 8)
      return parse_error(source + ": corrupt PNG: chunk '" + type + "' at byte " + std::to_string(p) + " declares " +
                         std::to_string(len) + " bytes, but only " + std::to_string(n - p - 8) + " follow");
    if (type == "IDAT" && len == 0 && !image_data)
      return parse_error(source + ": corrupt PNG: an empty IDAT chunk at byte " + std::to_string(p) + " before any image data");
    image_data = image_data || (type == "IDAT" && len > 0);
    if (type == "IEND") break;
    p += 12 + size_t(len);  // length, type, data, CRC
  }
  return Status::Ok();
}

Status bad_size(const std::string& source, uint64_t w, uint64_t h) {
  return unsupported(source + ": image size " + std::to_string(w) + "x" + std::to_string(h) + " outside 1.." +
                     std::to_string(kMaxImageSide) + " per side");
}

// Checks everything stb would trust (format, chunk and table sizes, sides) and reads the header:
// width, height and the stored channel count (1 grey, 2 grey + alpha, 3 RGB, 4 RGBA).
Status check_header(const uint8_t* data, size_t size, const std::string& source, int* w, int* h, int* comp) {
  if (data == nullptr || size == 0) return parse_error(source + ": empty file, not an image");
  if (!looks_like_png(data, size) && !looks_like_jpeg(data, size))
    return parse_error(source + ": unknown image format (not PNG or JPEG)");
  if (size > size_t(INT_MAX)) return unsupported(source + ": image file larger than 2 GiB");
  const int len = int(size);

  if (looks_like_jpeg(data, size)) GS_RETURN_IF_ERROR(check_jpeg_tables(data, size, source));
  if (looks_like_png(data, size)) GS_RETURN_IF_ERROR(check_png_chunks(data, size, source));
  uint64_t pw = 0, ph = 0;
  if (png_sides(data, size, &pw, &ph) && (pw == 0 || ph == 0 || pw > uint64_t(kMaxImageSide) || ph > uint64_t(kMaxImageSide)))
    return bad_size(source, pw, ph);
  if (!stbi_info_from_memory(data, len, w, h, comp))
    return parse_error(source + ": bad image header (" + stbi_failure_reason() + ")");
  if (*w <= 0 || *h <= 0 || *w > kMaxImageSide || *h > kMaxImageSide) return bad_size(source, uint64_t(*w), uint64_t(*h));
  return Status::Ok();
}

Expected<Image8> decode(const uint8_t* data, size_t size, int channels, const std::string& source) {
  if (channels != kChannelsAsStored && channels != 1 && channels != 3 && channels != 4)
    return invalid_argument(source + ": cannot decode to " + std::to_string(channels) + " channels (1, 3 or 4)");
  int w = 0, h = 0, comp = 0;
  GS_RETURN_IF_ERROR(check_header(data, size, source, &w, &h, &comp));
  if (channels == kChannelsAsStored) channels = (comp == 2 || comp == 4) ? 4 : 3;
  const int len = int(size);
  int dw = 0, dh = 0;
  uint8_t* pixels = stbi_load_from_memory(data, len, &dw, &dh, &comp, channels);
  if (pixels == nullptr) return parse_error(source + ": cannot decode image (" + stbi_failure_reason() + ")");
  if (dw != w || dh != h) {
    stbi_image_free(pixels);
    return parse_error(source + ": decoded size differs from the header");
  }
  Image8 img;
  img.width = w;
  img.height = h;
  img.channels = channels;
  try {
    img.pixels.assign(pixels, pixels + size_t(w) * size_t(h) * size_t(channels));
  } catch (...) {
    stbi_image_free(pixels);
    throw;
  }
  stbi_image_free(pixels);
  return img;
}

}  // namespace

Expected<Image8> decode_image(const uint8_t* data, size_t size, int channels, const std::string& source) {
  return detail::guarded(source, [&]() { return decode(data, size, channels, source); });
}

Expected<ImageInfo> read_image_info(const std::string& path) {
  return detail::guarded(path, [&]() -> Expected<ImageInfo> {
    auto bytes = platform::read_file(path, uint64_t(1) << 30);
    if (!bytes.ok()) return bytes.status();
    int w = 0, h = 0, comp = 0;
    GS_RETURN_IF_ERROR(check_header(bytes->data(), bytes->size(), path, &w, &h, &comp));
    ImageInfo info;
    info.width = w, info.height = h, info.has_alpha = comp == 2 || comp == 4;
    return info;
  });
}

Expected<Image8> read_image(const std::string& path, int channels) {
  return detail::guarded(path, [&]() -> Expected<Image8> {
    // JPEG/PNG of a kMaxImageSide^2 RGBA image compress well below this bound.
    auto bytes = platform::read_file(path, uint64_t(1) << 30);
    if (!bytes.ok()) return bytes.status();
    return decode(bytes->data(), bytes->size(), channels, path);
  });
}

}  // namespace gs::io
