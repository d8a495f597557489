// SPDX-License-Identifier: MIT
// bench_fixed_point: the on-device render path against the float one on a trained model's views.
// For each kernel table and thread count, every test view is rendered with the float path and with
// the on-device one (fixed-point blending, RenderOptions::fixed_point; and for a compact model the
// int8 decoder), and the Gaussian renderer's forward (project, bin, sort, blend) is timed apart from
// the anchor decoding. Prints median ms per view,
// the int/float speed ratio, and the PSNR of each path against the dataset images (8-bit) and of
// the fixed-point renders against the float ones (gs::metrics::psnr_u8, means over the views: one
// view the two paths render identically makes the agreement "inf"). --profile then times each stage
// of the float path (gs/stage_times.h) in one more pass over the views per thread count, and prints
// the stages side by side with each one's speed-up from the first thread count to the last.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench_common.h"
#include "gs/jobs/run_folder.h"
#include "gs/metrics/image_metrics.h"
#include "gs/model/model_renderer.h"
#include "gs/platform/clock.h"
#include "gs/platform/thread_pool.h"
#include "gs/stage_times.h"

namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::vector<uint8_t> to_u8(const std::vector<float>& rgb, size_t n) {
  std::vector<uint8_t> o(n);
  for (size_t i = 0; i < n; ++i) o[i] = uint8_t(std::lround(std::clamp(rgb[i], 0.0f, 1.0f) * 255.0f));
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_fixed_point: float vs fixed-point forward on a trained model's test views"};
  std::string model, dataset, isas, threads_list = "1,2", split = "test";
  int reps = 3, max_width = -1;
  bool profile = false;
  app.add_option("model", model, "Run folder, .hbgs or .hbgc model")->required();
  app.add_option("--dataset", dataset, "COLMAP dataset (default: the run's)");
  app.add_option("--isa", isas, "Kernel tables, comma separated (default: every SIMD table available)");
  app.add_option("--threads", threads_list, "Thread counts, comma separated")->capture_default_str();
  app.add_option("--reps", reps, "Timed passes over the views")->capture_default_str();
  app.add_option("--split", split, "Views: test, train or all")->capture_default_str();
  app.add_option("--max-width", max_width, "Downscale views to at most this width (default: as trained)");
  app.add_flag("--profile", profile, "Also time each stage of the float path per thread count (one more pass over the views)");
  CLI11_PARSE(app, argc, argv);

  gs::Expected<gs::jobs::ModelViews> mv = gs::jobs::load_model_views(model, dataset, max_width, split);
  if (!mv.ok()) {
    std::fprintf(stderr, "bench_fixed_point: %s\n", mv.status().to_string().c_str());
    return 1;
  }
  if (mv->cloud) {
    std::fprintf(stderr, "bench_fixed_point: %s holds plain Gaussians; this benchmark times anchor models\n", model.c_str());
    return 1;
  }
  const auto& views = mv->data->views;
  int max_w = 1, max_h = 1;
  for (const auto* v : views) max_w = std::max(max_w, v->camera.intr.width), max_h = std::max(max_h, v->camera.intr.height);
  std::vector<const gs::simd::KernelTable*> tables;
  if (isas.empty()) {
    const gs::simd::KernelTable* t[8];
    const int n = gs::simd::available_simd_kernel_tables(t, 8);
    tables.assign(t, t + n);
  } else {
    for (const std::string& name : gs::bench::split_list(isas)) {
      const gs::simd::KernelTable* t = gs::simd::kernel_table_by_name(name.c_str());
      if (!t) {
        std::fprintf(stderr, "bench_fixed_point: kernel table '%s' not available here\n", name.c_str());
        return 1;
      }
      tables.push_back(t);
    }
  }
  std::printf("bench_fixed_point: %s, %zu %s views of %s, up to %dx%d, %zu anchors, %d reps\n", mv->source.model_path.c_str(),
              views.size(), split.c_str(), mv->source.dataset.c_str(), max_w, max_h, mv->model.anchor_count, reps);
  std::printf("  forward = Gaussian renderer (project, bin, sort, blend); decode = anchor MLPs\n");
  std::printf("  decode: float MLPs, and for a compact model the int8 decoder (qmlp_fwd) on the fixed-point side\n");
  std::printf("  %-7s %3s  %10s %10s %7s  %10s %10s  %9s %9s %11s\n", "isa", "thr", "float fwd", "int fwd", "ratio",
              "dec float", "dec int", "PSNR flt", "PSNR int", "int vs flt");
  for (const gs::simd::KernelTable* kt : tables) {
    std::vector<std::pair<int, gs::StageTimes>> profiles;  // per thread count, the float path's stages
    for (const std::string& tl : gs::bench::split_list(threads_list)) {
      gs::platform::ThreadPool pool(std::stoi(tl));
      gs::model::ModelRenderer renderer;
      if (gs::Status st = renderer.init(mv->model, max_w, max_h, &pool, kt); !st.ok()) {
        std::fprintf(stderr, "bench_fixed_point: %s\n", st.to_string().c_str());
        return 1;
      }
      std::vector<double> fwd[2], dec[2];
      double psnr[2] = {0, 0}, agree = 0;
      std::vector<float> rgb(size_t(max_w) * size_t(max_h) * 3);
      for (int rep = -1; rep < reps; ++rep) {  // rep -1: warm-up and image metrics
        for (const auto* v : views) {
          const size_t n = size_t(v->camera.intr.width) * size_t(v->camera.intr.height) * 3;
          std::vector<uint8_t> out[2];
          for (int fixed = 0; fixed < 2; ++fixed) {
            gs::model::ModelRenderOptions ro;
            ro.fixed_point_raster = fixed == 1;
            ro.int8_mlp = fixed == 1 ? mv->compact.get() : nullptr;  // the int8 decoder too, for a compact model
            if (gs::Status st = renderer.set_options(ro); !st.ok()) {
              std::fprintf(stderr, "bench_fixed_point: %s\n", st.to_string().c_str());
              return 1;
            }
            if (gs::Status st = renderer.render(mv->model, v->camera, rgb.data()); !st.ok()) {
              std::fprintf(stderr, "bench_fixed_point: %s: %s\n", v->name.c_str(), st.to_string().c_str());
              return 1;
            }
            if (rep >= 0) {
              fwd[fixed].push_back(renderer.last_forward_ms());
              dec[fixed].push_back(renderer.last_decode_ms());
            } else {
              out[fixed] = to_u8(rgb, n);
              psnr[fixed] += gs::metrics::psnr_u8(out[fixed].data(), v->image.pixels.data(), n) / double(views.size());
            }
          }
          if (rep < 0) agree += gs::metrics::psnr_u8(out[0].data(), out[1].data(), n) / double(views.size());
        }
      }
      const double f = median(fwd[0]), q = median(fwd[1]);
      std::printf("  %-7s %3d  %8.2f ms %8.2f ms %6.2fx  %7.2f ms %7.2f ms  %9.3f %9.3f %8.1f dB\n", kt->isa,
                  pool.num_threads(), f, q, q > 0 ? f / q : 0.0, median(dec[0]), median(dec[1]), psnr[0], psnr[1], agree);
      std::fflush(stdout);
      if (profile) {
        if (gs::Status st = renderer.set_options(gs::model::ModelRenderOptions{}); !st.ok()) {
          std::fprintf(stderr, "bench_fixed_point: %s\n", st.to_string().c_str());
          return 1;
        }
        gs::StageTimes times;
        renderer.set_stage_times(&times);
        for (const auto* v : views) {
          const uint64_t t0 = gs::platform::now_ns();
          if (gs::Status st = renderer.render(mv->model, v->camera, rgb.data()); !st.ok()) {
            std::fprintf(stderr, "bench_fixed_point: %s: %s\n", v->name.c_str(), st.to_string().c_str());
            return 1;
          }
          times.finish_iteration(gs::platform::now_ns() - t0);
        }
        renderer.set_stage_times(nullptr);
        profiles.emplace_back(pool.num_threads(), times);
      }
    }
    if (profiles.empty()) continue;
    // The float path's stages, ms per view (means over the views), per thread count.
    std::printf("\n  %s float path by stage, mean ms per view (%zu views)\n  %-16s", kt->isa, views.size(), "stage");
    for (const auto& p : profiles) std::printf(" %8dT", p.first);
    if (profiles.size() > 1) std::printf("  speed-up");
    std::printf("\n");
    auto row = [&](const char* name, auto ms_of) {
      std::printf("  %-16s", name);
      for (const auto& p : profiles) std::printf(" %8.3f ", ms_of(p.second));
      const double first = ms_of(profiles.front().second), last = ms_of(profiles.back().second);
      if (profiles.size() > 1 && last > 0) std::printf("  %7.2fx", first / last);
      std::printf("\n");
    };
    for (int s = 0; s < gs::kStageCount; ++s) {
      bool any = false;
      for (const auto& p : profiles) any = any || p.second.ns[s] > 0;
      if (!any) continue;
      row(gs::stage_name(s), [&](const gs::StageTimes& t) { return t.ms_per_iteration(s); });
    }
    row("total", [](const gs::StageTimes& t) { return t.profiled_ms_per_iteration(); });
  }
  return 0;
}
