// SPDX-License-Identifier: MIT
// hbgs entry point: builds the CLI11 command tree, maps parse errors to exit code 2, and runs the
// chosen subcommand (each lives in its own cmd_*.cpp).
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "common.h"
#include "gs/platform/memory.h"
#include "gs/simd/kernel_table.h"

#ifndef HBGS_VERSION
#define HBGS_VERSION "unknown"
#endif

namespace {

std::string version_text() {
  const gs::simd::KernelTable& best = gs::simd::best_kernel_table();
  std::string text = std::string("hbgs ") + HBGS_VERSION + "\nkernel ISA: " + best.isa + " (" +
                     std::to_string(best.lanes) + " float lanes)";
#ifdef HBGS_HAVE_SYNTH
  text += "\nsynth: available (Embree)";
#else
  text += "\nsynth: unavailable (built without Embree)";
#endif
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  gs::platform::release_large_blocks_promptly();  // resident memory follows what is held (docs/MODEL.md)
  CLI::App app("hbgs: 3D Gaussian splatting on the CPU", "hbgs");
  app.set_version_flag("--version", version_text, "Print the version and the kernel ISA, then exit");
  app.require_subcommand(1);
  app.fallthrough(false);

#ifdef HBGS_DEVICE
  // hbgs-device: the on-device subset (training, evaluation, rendering, registration, tracking,
  // compact files, export; no capture, video or synthetic scenes), linked without FFmpeg, libcamera
  // and Embree, so its footprint is the library's.
  const hbgs::cli::Command commands[] = {
      hbgs::cli::add_train_command(app),    hbgs::cli::add_eval_command(app),    hbgs::cli::add_render_command(app),
      hbgs::cli::add_register_command(app), hbgs::cli::add_track_command(app),   hbgs::cli::add_compact_command(app),
      hbgs::cli::add_export_command(app),
  };
#else
  const hbgs::cli::Command commands[] = {
      hbgs::cli::add_synth_command(app),  hbgs::cli::add_train_command(app), hbgs::cli::add_eval_command(app),
      hbgs::cli::add_render_command(app), hbgs::cli::add_demo_command(app),  hbgs::cli::add_bench_command(app),
      hbgs::cli::add_register_command(app), hbgs::cli::add_track_command(app),   hbgs::cli::add_ingest_command(app),
      hbgs::cli::add_capture_command(app),
      hbgs::cli::add_compare_poses_command(app), hbgs::cli::add_compact_command(app), hbgs::cli::add_export_command(app),
      hbgs::cli::add_report_command(app),
  };

  if (hbgs::cli::bench_passes_through(argc, argv)) {
    std::vector<std::string> rest(argv + 2, argv + argc);
    if (!rest.empty() && rest.front() == "--") rest.erase(rest.begin());
    return hbgs::cli::run_bench(rest);
  }
#endif

  // A first word that is not a command gets a message naming it (CLI11 would only say that a
  // subcommand is required).
  if (argc > 1 && argv[1][0] != '-') {
    std::string names;
    bool known = false;
    for (const CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
      known = known || sub->get_name() == argv[1];
      names += (names.empty() ? "" : ", ") + sub->get_name();
    }
    if (!known) {
      std::fprintf(stderr, "hbgs: unknown command '%s'; the commands are: %s (hbgs --help describes them)\n", argv[1], names.c_str());
      return hbgs::cli::kExitUsage;
    }
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints help / version / the usage error
    return code == 0 ? hbgs::cli::kExitOk : hbgs::cli::kExitUsage;
  }

  try {
    for (const hbgs::cli::Command& c : commands)
      if (c.app->parsed()) return c.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hbgs: error: %s\n", e.what());
    return hbgs::cli::kExitRuntime;
  }
  return hbgs::cli::kExitUsage;  // unreachable: require_subcommand(1)
}
