// SPDX-License-Identifier: MIT
// Shared option wiring and printing for the ingest and capture subcommands: the flags bind to
// gs::capture::IngestOptions (gs/capture/ingest.h), which holds every default.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "gs/capture/ingest.h"

namespace hbgs::cli {

// out_required: false for `capture`, whose --list needs no output folder (run checks it then).
void add_ingest_options(CLI::App* sub, std::string* out, gs::capture::IngestOptions* options, bool out_required);
void print_progress(const std::string& line);
void print_ingest_summary(const gs::capture::IngestReport& report, const std::string& out, double seconds);

}  // namespace hbgs::cli
