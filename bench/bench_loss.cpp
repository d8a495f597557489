// SPDX-License-Identifier: MIT
// bench_loss: the photometric loss kernels (L1 + SSIM) of every kernel table, single-threaded, on
// random image pairs: forward and backward (which recomputes the forward), minimum ms over the
// repetitions (the least noisy figure on a shared machine) and megavalues (3 W H) per second.
// Sizes default to 393x293 (the test size) and 980x545.
#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/simd/kernel_table.h"
#include "gs/simd/loss.h"

int main(int argc, char** argv) {
  CLI::App app{"bench_loss: photometric loss kernels per kernel table"};
  std::string sizes = "393x293,980x545";
  int reps = 7;
  app.add_option("--sizes", sizes, "comma-separated WxH list");
  app.add_option("--reps", reps, "timed repetitions");
  CLI11_PARSE(app, argc, argv);

  const gs::bench::MachineInfo m = gs::bench::machine_info();
  std::printf("cpu: %s (%s), load %.2f\n", m.cpu_model.c_str(), gs::bench::format_mhz(m).c_str(),
              gs::bench::load_average());
  const gs::simd::LossParams p = gs::simd::make_loss_params();
  gs::bench::HarnessOptions opt;
  opt.reps = reps;
  std::printf("%-10s %-7s %10s %10s %10s %10s\n", "size", "isa", "fwd min ms", "bwd min ms", "fwd MV/s", "bwd MV/s");
  for (const std::string& s : gs::bench::split_list(sizes)) {
    int W = 0, H = 0;
    gs::bench::parse_size(s, &W, &H);
    const size_t n = size_t(3) * W * H;
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<float> u(0, 1);
    std::vector<float> image(n), target(n), v_image(n), scratch(gs::simd::loss_scratch_floats(W, H));
    for (size_t e = 0; e < n; ++e) {
      target[e] = u(rng);
      image[e] = std::min(1.0f, std::max(0.0f, target[e] + 0.2f * (u(rng) - 0.5f)));
    }
    for (const gs::simd::KernelTable* kt : gs::bench::all_kernel_tables()) {
      double l1 = 0, ssim = 0;
      const gs::bench::Timing tf = gs::bench::measure(
          [&] { kt->loss_fwd(&p, W, H, image.data(), target.data(), scratch.data(), &l1, &ssim); }, opt);
      const gs::bench::Timing tb = gs::bench::measure(
          [&] {
            kt->loss_bwd(&p, W, H, image.data(), target.data(), 1.0, scratch.data(), v_image.data(), nullptr, nullptr);
          },
          opt);
      std::printf("%-10s %-7s %10.3f %10.3f %10.1f %10.1f\n", s.c_str(), kt->isa, tf.min_ms, tb.min_ms,
                  double(n) / (1e3 * tf.min_ms), double(n) / (1e3 * tb.min_ms));
    }
  }
  return 0;
}
