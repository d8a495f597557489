// SPDX-License-Identifier: MIT
// Static rANS over bytes (gs/model/byte_rans.h): one frequency table per stream, 14-bit
// probabilities, a 32-bit state renormalised a byte at a time; hbgs's own implementation.
#include "gs/model/byte_rans.h"

#include <algorithm>

namespace gs::model::detail {

namespace {

constexpr int kProbBits = 14;
constexpr uint32_t kProbScale = 1u << kProbBits;
constexpr uint32_t kRansL = 1u << 23;  // state kept in [L, 2^31)

void put_varint(std::vector<uint8_t>* out, uint64_t v) {
  while (v >= 0x80) {
    out->push_back(uint8_t(v | 0x80));
    v >>= 7;
  }
  out->push_back(uint8_t(v));
}

bool get_varint(const uint8_t* d, size_t n, size_t* pos, uint64_t* v) {
  uint64_t r = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (*pos >= n) return false;
    const uint8_t b = d[(*pos)++];
    r |= uint64_t(b & 0x7f) << shift;
    if (!(b & 0x80)) {
      *v = r;
      return true;
    }
  }
  return false;
}

// Frequencies summing to kProbScale, >= 1 for every symbol that occurs.
void normalize(const uint64_t counts[256], size_t n, uint32_t freq[256]) {
  int64_t sum = 0;
  for (int s = 0; s < 256; ++s) {
    freq[s] = counts[s] ? uint32_t(std::max<uint64_t>(1, (counts[s] * kProbScale + n / 2) / n)) : 0;
    sum += freq[s];
  }
  while (sum != int64_t(kProbScale)) {
    int big = 0;
    for (int s = 1; s < 256; ++s) big = freq[s] > freq[big] ? s : big;
    if (sum < int64_t(kProbScale)) {
      freq[big] += uint32_t(int64_t(kProbScale) - sum);
      sum = kProbScale;
    } else {
      const uint32_t take = uint32_t(std::min<int64_t>(sum - int64_t(kProbScale), int64_t(freq[big]) - 1));
      freq[big] -= take;
      sum -= take;
    }
  }
}

}  // namespace

void rans_encode_bytes(const uint8_t* sym, size_t n, std::vector<uint8_t>* out) {
  if (n == 0) return;
  uint64_t counts[256] = {};
  for (size_t i = 0; i < n; ++i) ++counts[sym[i]];
  uint32_t freq[256], start[256];
  normalize(counts, n, freq);
  for (uint32_t s = 0, acc = 0; s < 256; ++s) start[s] = acc, acc += freq[s];
  // Table: nonzero frequencies as varints, a run of absent symbols as 0 then its length.
  for (int s = 0; s < 256;) {
    if (freq[s]) {
      put_varint(out, freq[s]);
      ++s;
    } else {
      int r = 0;
      while (s + r < 256 && !freq[s + r]) ++r;
      put_varint(out, 0);
      put_varint(out, uint64_t(r));
      s += r;
    }
  }
  std::vector<uint8_t> rev;
  rev.reserve(n / 2 + 8);
  uint32_t x = kRansL;
  for (size_t i = n; i-- > 0;) {
    const uint32_t f = freq[sym[i]];
    const uint32_t x_max = ((kRansL >> kProbBits) << 8) * f;
    while (x >= x_max) {
      rev.push_back(uint8_t(x & 0xff));
      x >>= 8;
    }
    x = ((x / f) << kProbBits) + (x % f) + start[sym[i]];
  }
  for (int b = 0; b < 4; ++b) rev.push_back(uint8_t(x >> (8 * b)));
  put_varint(out, rev.size());
  out->insert(out->end(), rev.rbegin(), rev.rend());
}

bool rans_decode_bytes(const uint8_t* data, size_t size, size_t* pos, size_t n, uint8_t* symbols, std::string* error) {
  if (n == 0) return true;
  uint32_t freq[256] = {}, start[256];
  uint64_t sum = 0;
  for (int s = 0; s < 256;) {
    uint64_t v;
    if (!get_varint(data, size, pos, &v)) return *error = "frequency table truncated", false;
    if (v == 0) {
      uint64_t r;
      if (!get_varint(data, size, pos, &r)) return *error = "frequency table truncated", false;
      if (r == 0 || r > uint64_t(256 - s)) return *error = "frequency table run of " + std::to_string(r) + " absent symbols at symbol " + std::to_string(s), false;
      s += int(r);
    } else {
      if (v > kProbScale) return *error = "frequency " + std::to_string(v) + " above " + std::to_string(kProbScale), false;
      freq[s++] = uint32_t(v);
      sum += v;
    }
  }
  if (sum != kProbScale) return *error = "frequencies sum to " + std::to_string(sum) + ", expected " + std::to_string(kProbScale), false;
  uint64_t len;
  if (!get_varint(data, size, pos, &len)) return *error = "payload length truncated", false;
  if (len < 4 || len > size - *pos)
    return *error = "payload of " + std::to_string(len) + " bytes (at least 4, at most the " + std::to_string(size - *pos) + " left)", false;
  std::vector<uint8_t> slot_sym(kProbScale);
  for (uint32_t s = 0, acc = 0; s < 256; ++s) {
    start[s] = acc;
    std::fill_n(slot_sym.begin() + acc, freq[s], uint8_t(s));
    acc += freq[s];
  }
  const uint8_t* p = data + *pos;
  const uint8_t* end = p + len;
  uint32_t x = uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | uint32_t(p[3]);
  p += 4;
  if (x < kRansL || x >= (1u << 31)) return *error = "initial coder state out of range", false;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t slot = x & (kProbScale - 1);
    const uint8_t s = slot_sym[slot];
    symbols[i] = s;
    x = freq[s] * (x >> kProbBits) + slot - start[s];
    while (x < kRansL) {
      if (p == end) return *error = "payload ends after " + std::to_string(i + 1) + " of " + std::to_string(n) + " symbols", false;
      x = (x << 8) | *p++;
    }
  }
  if (p != end || x != kRansL) return *error = "payload does not end where its last symbol does (corrupt stream)", false;
  *pos += size_t(len);
  return true;
}

}  // namespace gs::model::detail
