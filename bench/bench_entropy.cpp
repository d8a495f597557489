// SPDX-License-Identifier: MIT
// bench_entropy: the compact model file's entropy coder (static rANS per byte stream,
// gs/model/byte_rans.h) against libzstd at levels 3 and 19, on the byte streams a real compact
// model file codes. The streams are rebuilt from the loaded model exactly as serialize_compact
// lays them out (model::compact_streams: positions 9, offset scales 2, offsets 3k, log-scales 12,
// features F, image features 13 in mode paper; one byte per anchor each). Reported per coder: total coded bytes,
// bits per symbol, and decode speed (MB/s of decoded bytes, single thread, minimum and median of
// the repetitions). zstd is measured two ways: one frame per stream (what replacing rANS stream by
// stream would give) and one frame over all streams one after the other.
//   bench_entropy --model MODEL.hbgc [--reps N] [--json FILE]
#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <zstd.h>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/model/byte_rans.h"
#include "gs/model/compact_model.h"

namespace gs::bench {
namespace {

struct Stream {
  std::string group;
  std::vector<uint8_t> bytes;
};

// serialize_compact's coded streams of a model, in file order (gs/model/compact_model.h).
std::vector<Stream> coded_streams(const model::CompactModel& m) {
  std::vector<Stream> out;
  for (model::CompactStream& cs : model::compact_streams(m)) out.push_back(Stream{std::move(cs.group), std::move(cs.symbols)});
  return out;
}

struct Result {
  explicit Result(std::string name) : coder(std::move(name)) {}
  std::string coder;
  size_t bytes = 0;
  Timing decode;
  bool ok = true;
};

int run(int argc, char** argv) {
  CLI::App app{"bench_entropy: rANS vs zstd on a compact model file's byte streams"};
  std::string model_path, json_path;
  int reps = 20;
  app.add_option("--model", model_path, "compact model file (.hbgc, from hbgs compact)")->required();
  app.add_option("--reps", reps, "timed decode repetitions")->check(CLI::PositiveNumber);
  app.add_option("--json", json_path, "also write the figures as JSON to this file");
  CLI11_PARSE(app, argc, argv);

  Expected<model::CompactModel> m = model::load_compact(model_path);
  if (!m.ok()) {
    std::fprintf(stderr, "bench_entropy: %s\n", m.status().to_string().c_str());
    return 1;
  }
  const std::vector<Stream> streams = coded_streams(*m);
  size_t raw = 0;
  for (const Stream& s : streams) raw += s.bytes.size();
  Expected<std::vector<uint8_t>> file = platform::read_file(model_path);
  const uint64_t file_bytes = file.ok() ? file->size() : 0;
  const MachineInfo mi = machine_info();
  std::printf("bench_entropy: %s, %s, load average %.2f, zstd %s\n", mi.cpu_model.c_str(), format_mhz(mi).c_str(),
              load_average(), ZSTD_versionString());
  std::printf("  %s: %llu bytes, %zu anchors, %zu coded streams of %zu bytes (%zu bytes raw)\n", model_path.c_str(),
              (unsigned long long)file_bytes, m->anchor_count, streams.size(), m->anchor_count, raw);
  HarnessOptions ho;
  ho.warmup = 2;
  ho.reps = reps;
  ho.min_reps = 3;
  ho.max_seconds = 3.0;
  std::vector<Result> results;
  std::vector<uint8_t> decoded(raw);

  {  // rANS, as the file codes them: one stream after the other in one buffer
    Result r("rANS (file's coder)");
    std::vector<uint8_t> coded;
    for (const Stream& s : streams) model::detail::rans_encode_bytes(s.bytes.data(), s.bytes.size(), &coded);
    r.bytes = coded.size();
    r.decode = measure(
        [&] {
          size_t pos = 0, at = 0;
          std::string error;
          for (const Stream& s : streams) {
            r.ok &= model::detail::rans_decode_bytes(coded.data(), coded.size(), &pos, s.bytes.size(), decoded.data() + at, &error);
            at += s.bytes.size();
          }
        },
        ho);
    size_t at = 0;
    for (const Stream& s : streams) {
      r.ok &= std::equal(s.bytes.begin(), s.bytes.end(), decoded.begin() + long(at));
      at += s.bytes.size();
    }
    results.push_back(r);
  }
  ZSTD_DCtx* dctx = ZSTD_createDCtx();
  for (int level : {3, 19}) {
    {  // one frame per stream
      Result r("zstd " + std::to_string(level) + ", a frame per stream");
      std::vector<std::vector<uint8_t>> frames;
      for (const Stream& s : streams) {
        std::vector<uint8_t> f(ZSTD_compressBound(s.bytes.size()));
        f.resize(ZSTD_compress(f.data(), f.size(), s.bytes.data(), s.bytes.size(), level));
        r.bytes += f.size();
        frames.push_back(std::move(f));
      }
      r.decode = measure(
          [&] {
            size_t at = 0;
            for (size_t k = 0; k < streams.size(); ++k) {
              const size_t n = streams[k].bytes.size();
              r.ok &= ZSTD_decompressDCtx(dctx, decoded.data() + at, n, frames[k].data(), frames[k].size()) == n;
              at += n;
            }
          },
          ho);
      results.push_back(r);
    }
    {  // one frame over all streams
      Result r("zstd " + std::to_string(level) + ", one frame");
      std::vector<uint8_t> all;
      for (const Stream& s : streams) all.insert(all.end(), s.bytes.begin(), s.bytes.end());
      std::vector<uint8_t> f(ZSTD_compressBound(all.size()));
      f.resize(ZSTD_compress(f.data(), f.size(), all.data(), all.size(), level));
      r.bytes = f.size();
      r.decode = measure([&] { r.ok &= ZSTD_decompressDCtx(dctx, decoded.data(), raw, f.data(), f.size()) == raw; }, ho);
      r.ok &= decoded == all;
      results.push_back(r);
    }
  }
  ZSTD_freeDCtx(dctx);

  std::printf("  %-28s %10s %8s %9s %14s %14s\n", "coder", "bytes", "bits/B", "vs rANS", "decode MB/s min", "(median)");
  nlohmann::json j = {{"model", model_path}, {"file_bytes", file_bytes}, {"anchors", m->anchor_count},
                      {"streams", streams.size()}, {"raw_bytes", raw}, {"zstd", ZSTD_versionString()},
                      {"cpu", mi.cpu_model}, {"coders", nlohmann::json::array()}};
  for (const Result& r : results) {
    const double mbs_best = double(raw) / (r.decode.min_ms * 1e-3) / 1e6, mbs_med = double(raw) / (r.decode.median_ms * 1e-3) / 1e6;
    std::printf("  %-28s %10zu %8.3f %+8.1f%% %14.0f %14.0f%s\n", r.coder.c_str(), r.bytes, 8.0 * double(r.bytes) / double(raw),
                100.0 * (double(r.bytes) / double(results[0].bytes) - 1.0), mbs_best, mbs_med, r.ok ? "" : "  DECODE MISMATCH");
    j["coders"].push_back({{"coder", r.coder}, {"bytes", r.bytes}, {"decode_ms_min", r.decode.min_ms},
                           {"decode_ms_median", r.decode.median_ms}, {"decode_mb_s", mbs_best}, {"ok", r.ok}});
  }
  // Where the bytes go: rANS per group of streams.
  std::printf("  per group (rANS bytes / raw bytes):");
  for (size_t k = 0; k < streams.size();) {
    const std::string& g = streams[k].group;
    std::vector<uint8_t> coded;
    size_t group_raw = 0;
    for (; k < streams.size() && streams[k].group == g; ++k) {
      model::detail::rans_encode_bytes(streams[k].bytes.data(), streams[k].bytes.size(), &coded);
      group_raw += streams[k].bytes.size();
    }
    std::printf(" %s %zu/%zu;", g.c_str(), coded.size(), group_raw);
  }
  std::printf("\n");
  if (!json_path.empty() && !platform::write_file_atomic(json_path, j.dump(2) + "\n").ok()) {
    std::fprintf(stderr, "bench_entropy: cannot write %s\n", json_path.c_str());
    return 1;
  }
  for (const Result& r : results)
    if (!r.ok) return 1;
  return 0;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
