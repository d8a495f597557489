// SPDX-License-Identifier: MIT
// Options shared by `hbgs ingest` and `hbgs capture` (output folder, frame count, COLMAP settings)
// and their progress and summary printing.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "gs/capture/ingest.h"

namespace hbgs::cli {

struct IngestCommonArgs {
  std::string out;
  int frames = 100;
  double blur_ratio = 0.6;
  std::string matcher = "sequential";
  std::string colmap = "colmap";
  int max_width = 1600;
  int threads = 0;
  bool force = false;
  bool keep_work = false;
};

// out_required: false for `capture`, whose --list needs no output folder (run checks it then).
void add_ingest_options(CLI::App* sub, IngestCommonArgs* args, bool out_required);
// Fills options; prints the error and returns kExitUsage on a bad value.
int ingest_options_from(const IngestCommonArgs& args, const char* cmd, gs::capture::IngestOptions* out);
void print_progress(const std::string& line);
void print_ingest_summary(const gs::capture::IngestReport& report, const std::string& out, double seconds);

}  // namespace hbgs::cli
