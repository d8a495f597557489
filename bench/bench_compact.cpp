// SPDX-License-Identifier: MIT
// bench_compact: where the bytes and the error of a compact model file go. For a trained run it
// makes the compact model (as `hbgs compact` does), prints the file's sections as the writer
// reports them (coded bytes, bytes per anchor, the order-0 entropy of the coded symbols and the
// coder's overhead over it), then the test PSNR of the float model with one field at a time
// replaced by its dequantised value (the rows the compact model keeps), so each field's share of
// the accuracy loss is measured, and the decode time of the file (minimum of the repetitions).
//   bench_compact RUN [--reps N] [--no-attribution] [--delta-entropy] [quantisation options]
//   bench_compact RUN --time-file A.hbgc [--time-file B.hbgc] [--reps N]   (decode time only)
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench_common.h"
#include "gs/jobs/run_folder.h"
#include "gs/model/compact_model.h"
#include "gs/model/evaluate.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"

namespace {

using gs::model::HybridModel;

// The float rows listed in rows (in that order), with the MLPs of the float model.
HybridModel take_rows(const HybridModel& m, const std::vector<size_t>& rows) {
  HybridModel o = m;
  o.anchor_count = rows.size();
  auto gather = [&](const std::vector<float>& src, size_t w, std::vector<float>* dst) {
    std::vector<float> d(rows.size() * w);
    for (size_t i = 0; i < rows.size(); ++i) std::copy_n(src.begin() + std::ptrdiff_t(rows[i] * w), w, d.begin() + std::ptrdiff_t(i * w));
    *dst = std::move(d);
  };
  const size_t K = size_t(m.config.k), F = size_t(m.config.feature_dim);
  gather(m.positions, 3, &o.positions);
  gather(m.offsets, 3 * K, &o.offsets);
  gather(m.log_scales, 6, &o.log_scales);
  gather(m.features, F, &o.features);
  if (gs::model::uses_image_features(m.config.image_features)) gather(m.image_raw, gs::model::kImageRawDim, &o.image_raw);
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_compact: the compact file's bytes per section and each field's share of the PSNR loss"};
  std::string input;
  int reps = 5, threads = 0, residual_bits = 8;
  bool no_attribution = false;
  app.add_option("run", input, "Run folder or float model file")->required();
  app.add_option("--reps", reps, "Decode repetitions")->check(CLI::Range(1, 1000));
  app.add_option("--threads", threads, "Threads (0: all)");
  app.add_option("--residual-bits", residual_bits, "Sub-voxel bits of the anchor positions");
  app.add_flag("--no-attribution", no_attribution, "Skip the per-field PSNR attribution");
  gs::model::CompactOptions co;
  app.add_option("--offset-levels", co.offset_levels, "Steps to an anchor's largest offset (1..127)");
  app.add_option("--feature-levels", co.feature_levels, "Steps to a feature channel's largest value (1..127)");
  app.add_option("--image-levels", co.image_levels, "Steps over an image feature channel's range (1..255)");
  app.add_option("--log-scale-step", co.log_scale_step, "Grid step of the log-scales (0: half precision)");
  bool no_fine = false, keep_offsets = false;
  app.add_option("--weighted-offsets", co.weighted_offsets, "Offset steps by the measured sensitivity of the views (0/1)");
  app.add_option("--weighted-features", co.weighted_features, "Feature steps by the decoders' first-layer weights (0/1)");
  app.add_flag("--keep-offsets", keep_offsets, "Store the offsets of neural Gaussians no view keeps");
  app.add_flag("--no-mlp-fine", no_fine, "Do not store the MLP weights' rounding remainders");
  bool delta_entropy = false;
  app.add_flag("--delta-entropy", delta_entropy, "Print each field's entropy as values and as differences to the previous row");
  std::vector<std::string> time_files;
  app.add_option("--time-file", time_files, "Also time decoding these .hbgc files (any version), then exit");
  CLI11_PARSE(app, argc, argv);
  for (const std::string& f : time_files) {
    auto bytes = gs::platform::read_file(f);
    if (!bytes.ok()) return std::fprintf(stderr, "%s\n", bytes.status().to_string().c_str()), 1;
    double best = 1e30;
    for (int i = 0; i < reps; ++i) {
      const double a = gs::platform::now_seconds();
      auto m = gs::model::deserialize_compact(bytes->data(), bytes->size(), f);
      best = std::min(best, gs::platform::now_seconds() - a);
      if (!m.ok()) return std::fprintf(stderr, "%s\n", m.status().to_string().c_str()), 1;
    }
    std::printf("%s: %zu bytes, decode %.2f ms (deserialize_compact, 1 thread, min of %d)\n", f.c_str(), bytes->size(), best * 1e3, reps);
  }
  if (!time_files.empty()) return 0;

  auto loaded = gs::jobs::load_model_views(input, "", -1, "all");
  if (!loaded.ok()) return std::fprintf(stderr, "%s\n", loaded.status().to_string().c_str()), 1;
  std::vector<gs::Camera> train;
  std::vector<const gs::io::DatasetView*> test;
  for (const gs::io::DatasetView* v : loaded->data->views) (v->is_test ? (void)test.push_back(v) : train.push_back(v->camera));
  gs::platform::ThreadPool pool(threads);
  co.residual_bits = residual_bits;
  co.mlp_fine = !no_fine;
  co.prune_offsets = !keep_offsets;
  gs::model::CompactStats st;
  const double t0 = gs::platform::now_seconds();
  auto cm = gs::model::compact_from_model(loaded->model, train, co, &pool, &st);
  if (!cm.ok()) return std::fprintf(stderr, "%s\n", cm.status().to_string().c_str()), 1;
  const double t_make = gs::platform::now_seconds() - t0;
  std::vector<gs::model::CompactSection> sections;
  const std::vector<uint8_t> file = gs::model::serialize_compact(*cm, &sections);
  const double M = double(cm->anchor_count);
  std::printf("%s: %zu of %zu anchors kept, %zu bytes (%.3f MB, %.2f bytes per anchor), made in %.1f s\n", input.c_str(),
              cm->anchor_count, size_t(cm->source_anchors), file.size(), double(file.size()) / 1e6, double(file.size()) / M, t_make);
  std::printf("offsets stored as 0 (Gaussian kept in no view): %zu of %zu\n", st.offsets_dropped, cm->anchor_count * size_t(cm->config.k));
  std::printf("%-22s %10s %8s %10s %10s %8s\n", "section", "bytes", "B/anchor", "symbols", "entropy B", "overhead");
  std::map<std::string, gs::model::CompactSection> groups;
  std::vector<std::string> order;
  for (const auto& s : sections) {
    if (!groups.count(s.group)) order.push_back(s.group), groups[s.group].group = s.group;
    auto& g = groups[s.group];
    g.bytes += s.bytes;
    g.symbols += s.symbols;
    g.entropy_bytes += s.entropy_bytes;
  }
  size_t total = 0;
  for (const auto& name : order) {
    const auto& g = groups[name];
    total += g.bytes;
    std::printf("%-22s %10zu %8.2f %10zu %10.0f %7.1f%%\n", name.c_str(), g.bytes, double(g.bytes) / M, g.symbols, g.entropy_bytes,
                g.entropy_bytes > 0 ? 100.0 * (double(g.bytes) / g.entropy_bytes - 1.0) : 0.0);
  }
  std::printf("%-22s %10zu %8.2f\n", "total", total, double(total) / M);

  if (delta_entropy) {  // would predicting a field from the previous row pay? (order-0 entropies)
    const auto& q = cm->pos_q;
    const size_t N = cm->anchor_count, F = size_t(cm->config.feature_dim), K3 = 3 * size_t(cm->config.k);
    auto spread = [](uint64_t v) {
      uint64_t r = 0;
      for (int b = 0; b < 21; ++b) r |= ((v >> b) & 1ull) << (3 * b);
      return r;
    };
    std::vector<std::pair<uint64_t, size_t>> mo(N);
    for (size_t i = 0; i < N; ++i) {
      const uint64_t x = q[3 * i] >> cm->residual_bits, y = q[3 * i + 1] >> cm->residual_bits, z = q[3 * i + 2] >> cm->residual_bits;
      mo[i] = {spread(x) | spread(y) << 1 | spread(z) << 2, i};
    }
    std::sort(mo.begin(), mo.end());
    auto H = [](const std::vector<int>& v) {
      std::map<int, size_t> c;
      for (int x : v) ++c[x];
      double b = 0;
      for (auto& kv : c) b -= double(kv.second) * std::log2(double(kv.second) / double(v.size()));
      return b / 8;
    };
    auto report = [&](const char* name, size_t C, auto&& val) {
      double raw = 0, sorted_delta = 0, file_delta = 0;
      for (size_t ch = 0; ch < C; ++ch) {
        std::vector<int> a(N), d(N), e(N);
        for (size_t i = 0; i < N; ++i) {
          a[i] = val(i, ch);
          d[i] = val(mo[i].second, ch) - (i ? val(mo[i - 1].second, ch) : 0);
          e[i] = val(i, ch) - (i ? val(i - 1, ch) : 0);
        }
        raw += H(a), sorted_delta += H(d), file_delta += H(e);
      }
      std::printf("%s: values %.0f B, differences in Morton order of the cells %.0f B, in file order %.0f B\n", name, raw, sorted_delta, file_delta);
    };
    report("features", F, [&](size_t i, size_t ch) { return int(cm->features[i * F + ch]); });
    report("offsets", K3, [&](size_t i, size_t ch) { return int(cm->offsets[i * K3 + ch]); });
    report("log-scales", 6, [&](size_t i, size_t ch) { return int(cm->log_scales[i * 6 + ch]); });
    report("image", 13, [&](size_t i, size_t ch) { return int(cm->image_raw[i * 13 + ch]); });
  }
  double best = 1e30;
  for (int i = 0; i < reps; ++i) {
    const double a = gs::platform::now_seconds();
    auto back = gs::model::deserialize_compact(file.data(), file.size(), "mem");
    const double b = gs::platform::now_seconds();
    if (!back.ok()) return std::fprintf(stderr, "%s\n", back.status().to_string().c_str()), 1;
    best = std::min(best, b - a);
  }
  std::printf("decode (deserialize_compact, 1 thread, min of %d): %.2f ms\n", reps, best * 1e3);

  if (no_attribution || test.empty()) return 0;
  gs::model::EvalOptions eo;
  eo.psnr_only = true;
  auto bg = gs::jobs::model_background(loaded->source, "");
  if (!bg.ok()) return std::fprintf(stderr, "%s\n", bg.status().to_string().c_str()), 1;
  std::copy(bg->rgb, bg->rgb + 3, eo.render.background);
  auto psnr = [&](const HybridModel& m) {
    auto e = gs::model::evaluate_views(m, test, eo, &pool);
    return e.ok() ? e->psnr : -1.0;
  };
  const HybridModel& fm = loaded->model;
  const HybridModel kept = take_rows(fm, st.source_rows);
  const HybridModel dq = gs::model::dequantize(*cm);
  const double p_float = psnr(fm), p_kept = psnr(kept), p_all = psnr(dq);
  std::printf("test PSNR: float %.3f, kept rows %.3f (%+.3f), compact %.3f (%+.3f)\n", p_float, p_kept, p_kept - p_float, p_all,
              p_all - p_float);
  struct Field {
    const char* name;
    std::vector<float> HybridModel::*member;
  };
  const Field fields[] = {{"positions", &HybridModel::positions},
                          {"offsets", &HybridModel::offsets},
                          {"log-scales", &HybridModel::log_scales},
                          {"features", &HybridModel::features},
                          {"image features", &HybridModel::image_raw}};
  for (const Field& f : fields) {
    if ((kept.*(f.member)).empty()) continue;
    HybridModel m = kept;
    m.*(f.member) = dq.*(f.member);
    const double p = psnr(m);
    std::printf("  only %-16s quantised: %.3f (%+.3f against the kept rows)\n", f.name, p, p - p_kept);
  }
  {
    HybridModel m = kept;
    for (int i = 0; i < gs::model::kMlpCount; ++i) m.mlps[i] = dq.mlps[i];
    const double p = psnr(m);
    std::printf("  only %-16s quantised: %.3f (%+.3f against the kept rows)\n", "MLPs", p, p - p_kept);
  }
  return 0;
}
