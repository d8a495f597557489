// SPDX-License-Identifier: MIT
// libFuzzer harness: the Niantic .spz reader. First byte even: the rest is the file (v2/v3: gzip
// framing, CRC, trailing bytes, the gzip-bomb cap; v4: the plain header, the table of contents and
// the ZSTD frames; the v4 seeds' frames store their bytes uncompressed, so mutations reach the
// attribute decoding). Odd: the rest is the decompressed stream of a v2/v3 file, which the harness
// gzips first, so that mutations reach the header, count and field decoding behind gzip's checksum.
#include <zlib.h>

#include <cstdint>
#include <vector>

#include "gs/io/splat_formats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  if (!(data[0] & 1)) {
    (void)gs::io::parse_spz(data + 1, size - 1, "fuzz.spz");
    return 0;
  }
  z_stream s{};
  if (deflateInit2(&s, 1, Z_DEFLATED, 16 + MAX_WBITS, 8, Z_DEFAULT_STRATEGY) != Z_OK) return 0;
  std::vector<uint8_t> gz(deflateBound(&s, uLong(size)) + 64);
  s.next_in = const_cast<Bytef*>(data + 1);
  s.avail_in = uInt(size - 1);
  s.next_out = gz.data();
  s.avail_out = uInt(gz.size());
  const int rc = deflate(&s, Z_FINISH);
  gz.resize(gz.size() - s.avail_out);
  deflateEnd(&s);
  if (rc == Z_STREAM_END) (void)gs::io::parse_spz(gz.data(), gz.size(), "fuzz.spz");
  return 0;
}
