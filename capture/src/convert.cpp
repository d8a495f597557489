// SPDX-License-Identifier: MIT
// Frame to RGB24 for every PixelFormat. YUYV and NV12 go through the best SIMD kernel table
// (bit-identical to gs/simd/convert.h's reference), RGB24 is a strided row copy, and MJPEG is
// decoded with stb_image after two checks stb does not make: UVC cameras often send baseline JPEGs
// without a DHT segment (the standard Annex K tables are implied, as in Motion-JPEG/AVI1), so
// those tables are inserted first; and a frame cut short in transfer (no EOI marker after the scan)
// is an error rather than an image whose lower part stb would silently fill with grey.
#include "gs/capture/convert.h"

#include <cstring>
#include <string>

#include "gs/io/image.h"
#include "gs/simd/kernel_table.h"

namespace gs::capture {
namespace {

// ITU-T T.81 Annex K, tables K.3 to K.6: the "typical" Huffman tables of baseline JPEG, as a
// DHT segment's content. Per table: Tc << 4 | Th (class 0 = DC, 1 = AC; destination 0 = luma,
// 1 = chroma), then BITS (number of codes of each length 1..16), then HUFFVAL (the symbols in
// code order). DC symbols are magnitude categories 0..11; AC symbols are run << 4 | size plus
// 0x00 (end of block) and 0xF0 (sixteen zeros).
constexpr uint8_t kDcLumaBits[16] = {0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0};
constexpr uint8_t kDcChromaBits[16] = {0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0};
constexpr uint8_t kDcValues[12] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};  // same for K.3 and K.4

constexpr uint8_t kAcLumaBits[16] = {0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d};
constexpr uint8_t kAcLumaValues[162] = {
    0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61, 0x07, 0x22, 0x71,
    0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52, 0xd1, 0xf0, 0x24, 0x33, 0x62, 0x72,
    0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x34, 0x35, 0x36, 0x37,
    0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59,
    0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83,
    0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3,
    0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3,
    0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2,
    0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
};

constexpr uint8_t kAcChromaBits[16] = {0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77};
constexpr uint8_t kAcChromaValues[162] = {
    0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61, 0x71, 0x13, 0x22,
    0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33, 0x52, 0xf0, 0x15, 0x62, 0x72, 0xd1,
    0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18, 0x19, 0x1a, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x35, 0x36,
    0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58,
    0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a,
    0x82, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a,
    0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba,
    0xc2, 0xc3, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda,
    0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8, 0xf9, 0xfa,
};

constexpr int bits_total(const uint8_t (&bits)[16]) {
  int n = 0;
  for (uint8_t b : bits) n += b;
  return n;
}
static_assert(bits_total(kDcLumaBits) == 12 && bits_total(kDcChromaBits) == 12, "K.3/K.4 have 12 symbols");
static_assert(bits_total(kAcLumaBits) == 162 && bits_total(kAcChromaBits) == 162, "K.5/K.6 have 162 symbols");

// FF C4, a 2-byte big-endian length counting itself, then the four tables.
constexpr size_t kDhtPayload = 2 + 4 * (1 + 16) + 12 + 12 + 162 + 162;

void append_table(std::vector<uint8_t>* out, uint8_t class_and_id, const uint8_t (&bits)[16], const uint8_t* values,
                  int count) {
  out->push_back(class_and_id);
  out->insert(out->end(), bits, bits + 16);
  out->insert(out->end(), values, values + count);
}

void append_default_dht(std::vector<uint8_t>* out) {
  out->push_back(0xff);
  out->push_back(0xc4);
  out->push_back(uint8_t(kDhtPayload >> 8));
  out->push_back(uint8_t(kDhtPayload & 0xff));
  append_table(out, 0x00, kDcLumaBits, kDcValues, 12);
  append_table(out, 0x10, kAcLumaBits, kAcLumaValues, 162);
  append_table(out, 0x01, kDcChromaBits, kDcValues, 12);
  append_table(out, 0x11, kAcChromaBits, kAcChromaValues, 162);
}

// What a walk over a JPEG's marker segments (SOI up to the first SOS) found.
struct JpegLayout {
  bool header_ok = false;  // SOI, then well-formed segments up to and including an SOS
  bool has_dht = false;
  size_t insert_at = 0;    // offset of the first SOFn or SOS marker: where a DHT may go
  bool has_eoi = false;    // an EOI marker follows the entropy-coded data
  std::string problem;     // why header_ok / has_eoi is false
};

std::string hex_byte(uint8_t b) {
  static const char kDigits[] = "0123456789ABCDEF";
  return std::string{kDigits[b >> 4], kDigits[b & 15]};
}

bool is_sof(uint8_t m) { return m >= 0xc0 && m <= 0xcf && m != 0xc4 && m != 0xc8 && m != 0xcc; }

JpegLayout scan_jpeg(const uint8_t* d, size_t n) {
  JpegLayout l;
  if (n < 4 || d[0] != 0xff || d[1] != 0xd8) {
    l.problem = "no JPEG start-of-image marker";
    return l;
  }
  size_t pos = 2;
  for (;;) {
    if (pos >= n || d[pos] != 0xff) {
      l.problem = "marker segments end before the scan (truncated or corrupt header at byte " + std::to_string(pos) + ")";
      return l;
    }
    while (pos < n && d[pos] == 0xff) ++pos;  // fill bytes
    if (pos >= n) {
      l.problem = "truncated inside a marker";
      return l;
    }
    const uint8_t m = d[pos++];
    const size_t marker_at = pos - 2;
    if (m == 0xd8 || m == 0x01 || (m >= 0xd0 && m <= 0xd7)) continue;  // no length field
    if (m == 0xd9) {
      l.problem = "end-of-image marker before any scan";
      return l;
    }
    if (pos + 2 > n) {
      l.problem = "truncated segment length";
      return l;
    }
    const size_t len = size_t(d[pos]) << 8 | d[pos + 1];
    if (len < 2 || pos + len > n) {
      l.problem = "segment 0xFF" + hex_byte(m) + " of " + std::to_string(len) + " bytes runs past the end";
      return l;
    }
    if (m == 0xc4) l.has_dht = true;
    if ((is_sof(m) || m == 0xda) && l.insert_at == 0) l.insert_at = marker_at;
    pos += len;
    if (m == 0xda) break;
  }
  l.header_ok = true;
  // Entropy-coded data: 0xFF is always followed by 0x00 (stuffing), RSTn or a real marker. UVC
  // payloads may carry padding after EOI, so any EOI from here on counts.
  for (size_t i = pos; i + 1 < n; ++i)
    if (d[i] == 0xff && d[i + 1] == 0xd9) {
      l.has_eoi = true;
      return l;
    }
  l.problem = "no end-of-image marker after the scan (frame truncated in transfer?)";
  return l;
}

}  // namespace

std::vector<uint8_t> insert_default_huffman_tables(const uint8_t* jpeg, size_t size) {
  const JpegLayout l = scan_jpeg(jpeg, size);
  std::vector<uint8_t> out;
  if (!l.header_ok || l.has_dht) {  // nothing to add, or nothing safe to add it to: a plain copy
    out.assign(jpeg, jpeg + size);
    return out;
  }
  out.reserve(size + 2 + kDhtPayload);
  out.insert(out.end(), jpeg, jpeg + l.insert_at);
  append_default_dht(&out);
  out.insert(out.end(), jpeg + l.insert_at, jpeg + size);
  return out;
}

namespace {

Status mjpeg_to_rgb(const FrameView& f, uint8_t* rgb, int32_t rgb_stride) {
  const uint8_t* data = f.planes[0].data;
  const size_t size = f.planes[0].size;
  const std::string what = "mjpeg frame " + std::to_string(f.sequence);
  const JpegLayout l = scan_jpeg(data, size);
  if (!l.header_ok || !l.has_eoi) return parse_error(what + ": corrupt JPEG: " + l.problem);
  std::vector<uint8_t> patched;
  if (!l.has_dht) {
    patched = insert_default_huffman_tables(data, size);
    data = patched.data();
  }
  const size_t len = l.has_dht ? size : patched.size();
  Expected<io::Image8> img = io::decode_image(data, len, 3, what);
  if (!img.ok()) return img.status();
  if (img->width != f.width || img->height != f.height)
    return invalid_argument(what + ": JPEG is " + std::to_string(img->width) + "x" + std::to_string(img->height) +
                            ", the stream's format says " + std::to_string(f.width) + "x" + std::to_string(f.height));
  const size_t row = size_t(f.width) * 3;
  for (int32_t y = 0; y < f.height; ++y) std::memcpy(rgb + int64_t(y) * rgb_stride, img->pixels.data() + size_t(y) * row, row);
  return Status::Ok();
}

}  // namespace

Status frame_to_rgb(const FrameView& frame, uint8_t* rgb, int32_t rgb_stride) {
  GS_RETURN_IF_ERROR(validate_frame(frame));
  if (rgb == nullptr) return invalid_argument("frame_to_rgb: no output buffer");
  if (int64_t(rgb_stride) < 3 * int64_t(frame.width))
    return invalid_argument("frame_to_rgb: output stride " + std::to_string(rgb_stride) + " bytes is less than 3 x " +
                            std::to_string(frame.width));
  const FramePlane* p = frame.planes;
  const simd::KernelTable& k = simd::best_kernel_table();
  switch (frame.format) {
    case PixelFormat::kRGB24:
      for (int32_t y = 0; y < frame.height; ++y)
        std::memcpy(rgb + int64_t(y) * rgb_stride, p[0].data + int64_t(y) * p[0].stride, size_t(frame.width) * 3);
      return Status::Ok();
    case PixelFormat::kYUYV:
      k.yuyv_to_rgb(frame.width, frame.height, p[0].data, p[0].stride, rgb, rgb_stride);
      return Status::Ok();
    case PixelFormat::kNV12:
      k.nv12_to_rgb(frame.width, frame.height, p[0].data, p[0].stride, p[1].data, p[1].stride, rgb, rgb_stride);
      return Status::Ok();
    case PixelFormat::kMJPEG: return mjpeg_to_rgb(frame, rgb, rgb_stride);
  }
  return invalid_argument("frame_to_rgb: unknown pixel format");
}

}  // namespace gs::capture
