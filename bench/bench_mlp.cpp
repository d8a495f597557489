// SPDX-License-Identifier: MIT
// bench_mlp: the decoder MLP kernels (mlp_fwd / mlp_bwd) of every kernel table, single-threaded,
// on the shapes hbgs trains with (7 offsets per anchor below 15,000 iterations: 52-32-7 tanh,
// 52-32-49 none, 52-32-21 sigmoid; 10 from there: 52-32-10 tanh, 52-32-70 none, 52-32-30 sigmoid;
// the image-feature MLP 13-32-16 none; without image features 36-32-70 none) at a batch of 3300
// rows (one decoder call of a real training iteration): median and minimum ms over the repetitions
// and GFLOP/s at the median. FLOPs count 2 per multiply-add:
// forward 2 B (I H + H O); backward with v_x 4 B (I H + H O) (v_W2 and v_h from the second layer,
// v_W1 and v_x from the first). Optionally writes JSON.
#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/simd/kernel_table.h"
#include "gs/simd/mlp.h"

namespace {

using gs::simd::MlpAct;
using gs::simd::MlpShape;

struct Problem {
  const char* name;
  MlpShape s;
};

const Problem kProblems[] = {
    {"52-32-7 tanh", {52, 32, 7, MlpAct::kTanh}},      {"52-32-49 none", {52, 32, 49, MlpAct::kNone}},
    {"52-32-21 sigm", {52, 32, 21, MlpAct::kSigmoid}},
    {"52-32-10 tanh", {52, 32, 10, MlpAct::kTanh}},    {"52-32-70 none", {52, 32, 70, MlpAct::kNone}},
    {"52-32-30 sigm", {52, 32, 30, MlpAct::kSigmoid}}, {"13-32-16 none", {13, 32, 16, MlpAct::kNone}},
    {"36-32-70 none", {36, 32, 70, MlpAct::kNone}},
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_mlp: decoder MLP kernels per kernel table"};
  int batch = 3300, reps = 15;
  std::string isa, json_path;
  app.add_option("--batch", batch, "rows per call")->check(CLI::Range(1, 1 << 24));
  app.add_option("--reps", reps, "timed repetitions")->check(CLI::Range(1, 100000));
  app.add_option("--isa", isa, "comma-separated kernel tables (default: all available)");
  app.add_option("--json", json_path, "write the results as JSON to this file");
  CLI11_PARSE(app, argc, argv);

  const gs::bench::MachineInfo m = gs::bench::machine_info();
  const double load0 = gs::bench::load_average();
  std::printf("cpu: %s (%s), load %.2f, batch %d\n", m.cpu_model.c_str(), gs::bench::format_mhz(m).c_str(), load0,
              batch);
  std::vector<std::string> want = gs::bench::split_list(isa);
  gs::bench::HarnessOptions opt;
  opt.reps = reps;
  opt.max_seconds = 2.0;
  opt.min_reps = 3;
  nlohmann::json rows = nlohmann::json::array();
  std::printf("%-14s %-7s %10s %9s %8s %10s %9s %8s\n", "shape", "isa", "fwd med ms", "min ms", "GFLOP/s",
              "bwd med ms", "min ms", "GFLOP/s");
  for (const Problem& pb : kProblems) {
    const MlpShape& s = pb.s;
    const size_t I = size_t(s.in), H = size_t(s.hidden), O = size_t(s.out), Bn = size_t(batch);
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<float> u(-1, 1);
    auto fill = [&](size_t n, float scale) {
      std::vector<float> v(n);
      for (float& e : v) e = scale * u(rng);
      return v;
    };
    const std::vector<float> x = fill(Bn * I, 1.0f), W1 = fill(H * I, 0.2f), b1 = fill(H, 0.2f), W2 = fill(O * H, 0.2f),
                             b2 = fill(O, 0.2f), v_y = fill(Bn * O, 1.0f);
    std::vector<float> hidden(Bn * H), y(Bn * O), v_x(Bn * I), v_W1(H * I), v_b1(H), v_W2(O * H), v_b2(O);
    const double flops_fwd = 2.0 * double(Bn) * double(I * H + H * O), flops_bwd = 2.0 * flops_fwd;
    for (const gs::simd::KernelTable* kt : gs::bench::all_kernel_tables()) {
      if (!want.empty() && std::find(want.begin(), want.end(), std::string(kt->isa)) == want.end()) continue;
      const gs::bench::Timing tf = gs::bench::measure(
          [&] {
            kt->mlp_fwd(&s, batch, x.data(), W1.data(), b1.data(), W2.data(), b2.data(), hidden.data(), y.data());
          },
          opt);
      const gs::bench::Timing tb = gs::bench::measure(
          [&] {
            kt->mlp_bwd(&s, batch, x.data(), W1.data(), b1.data(), W2.data(), b2.data(), hidden.data(), y.data(),
                        v_y.data(), v_x.data(), v_W1.data(), v_b1.data(), v_W2.data(), v_b2.data());
          },
          opt);
      const double gf = flops_fwd / (tf.median_ms * 1e6), gb = flops_bwd / (tb.median_ms * 1e6);
      std::printf("%-14s %-7s %10.3f %9.3f %8.2f %10.3f %9.3f %8.2f\n", pb.name, kt->isa, tf.median_ms, tf.min_ms, gf,
                  tb.median_ms, tb.min_ms, gb);
      std::fflush(stdout);
      rows.push_back({{"shape", pb.name}, {"in", s.in}, {"hidden", s.hidden}, {"out", s.out},
                      {"act2", int(s.act2)}, {"isa", kt->isa}, {"batch", batch},
                      {"fwd_ms", {{"reps", tf.reps}, {"median", tf.median_ms}, {"min", tf.min_ms}}},
                      {"bwd_ms", {{"reps", tb.reps}, {"median", tb.median_ms}, {"min", tb.min_ms}}},
                      {"fwd_gflops_at_median", gf}, {"bwd_gflops_at_median", gb}});
    }
  }
  if (!json_path.empty()) {
    nlohmann::json j;
    j["tool"] = "bench_mlp";
    j["cpu"] = m.cpu_model;
    j["cpu_mhz"] = m.cpu_mhz;
    j["load_average"] = load0;
    j["batch"] = batch;
    j["rows"] = rows;
    if (!gs::bench::write_output(json_path, j.dump(2) + "\n", "bench_mlp")) return 1;
  }
  return 0;
}
