// SPDX-License-Identifier: MIT
// Shared glue for the hbgs subcommands: how a subcommand registers itself, exit codes, error and
// progress printing, and the small timing/statistics helpers the summaries use.
#pragma once

#include <algorithm>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "gs/jobs/report.h"
#include "gs/jobs/train.h"
#include "gs/model/background.h"
#include "gs/platform/clock.h"
#include "gs/stats.h"

namespace hbgs::cli {

// Process exit codes (CLI11 parse errors are mapped to kExitUsage in main).
constexpr int kExitOk = 0;
constexpr int kExitRuntime = 1;
constexpr int kExitUsage = 2;
constexpr int kExitNotConverged = 3;  // hbgs register: a result whose verdict is not "converged"
constexpr int kExitNoPose = 3;        // hbgs track: no frame could be placed (every frame lost)

// A registered subcommand: its CLI11 node, and what to run once it has been parsed.
struct Command {
  CLI::App* app = nullptr;
  std::function<int()> run;
};

Command add_synth_command(CLI::App& parent);
Command add_render_command(CLI::App& parent);
Command add_bench_command(CLI::App& parent);
Command add_train_command(CLI::App& parent);
Command add_eval_command(CLI::App& parent);
Command add_compact_command(CLI::App& parent);
Command add_export_command(CLI::App& parent);
Command add_report_command(CLI::App& parent);
Command add_demo_command(CLI::App& parent);
Command add_register_command(CLI::App& parent);
Command add_ingest_command(CLI::App& parent);
Command add_capture_command(CLI::App& parent);
Command add_compare_poses_command(CLI::App& parent);
Command add_track_command(CLI::App& parent);

// `hbgs bench ARGS...` bypasses CLI11 (except `hbgs bench --help`): ARGS go to bench_render as given.
bool bench_passes_through(int argc, char** argv);
int run_bench(const std::vector<std::string>& pass_through);

// `hbgs train` (also run by `hbgs demo`): the job with its progress on stderr (unless quiet) and
// the summary on stdout.
int run_train(const gs::jobs::TrainRunOptions& options, bool quiet, gs::jobs::TrainRunSummary* summary);

// `hbgs report` (also run by `hbgs train --report` and `hbgs demo`): writes the page and prints
// what it holds. hbgs only (hbgs-device has no report command).
int run_report(const gs::jobs::ReportRunOptions& options);

// "hbgs <cmd>: error: <message>" on stderr; returns kExitRuntime so callers can `return fail(...)`.
inline int fail(const char* cmd, const std::string& message) {
  std::fflush(stdout);
  std::fprintf(stderr, "hbgs %s: error: %s\n", cmd, message.c_str());
  return kExitRuntime;
}

// Checks a --background value (black, white, random, r,g,b) at parse time.
inline CLI::Validator background_validator() {
  return CLI::Validator(
      [](std::string& s) {
        gs::Expected<gs::model::Background> b = gs::model::parse_background(s);
        return b.ok() ? std::string() : b.status().message();
      },
      "black|white|random|R,G,B");
}

// Wall-clock stopwatch on the platform's monotonic clock.
class Stopwatch {
 public:
  Stopwatch() : start_(gs::platform::now_seconds()) {}
  double seconds() const { return gs::platform::now_seconds() - start_; }
  double ms() const { return 1e3 * seconds(); }

 private:
  double start_;
};

}  // namespace hbgs::cli
