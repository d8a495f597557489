// SPDX-License-Identifier: MIT
// `hbgs ingest VIDEO|FOLDER --out DATASET`: frame selection plus COLMAP, giving a dataset that
// `hbgs train` reads (see gs/capture/ingest.h for the pipeline and its guarantees).
#include <cstdio>
#include <memory>
#include <string>

#include "capture_cli.h"
#include "common.h"
#include "gs/capture/ingest.h"

namespace hbgs::cli {
namespace {

struct IngestArgs {
  std::string input, out;
  gs::capture::IngestOptions options;
};

int run_ingest(const IngestArgs& a) {
  const std::string input = a.input;
  gs::capture::IngestReport report;
  Stopwatch sw;
  const gs::Status st = gs::capture::ingest([input] { return gs::capture::open_input(input); }, a.out, a.options,
                                            print_progress, &report);
  if (!st.ok()) return fail("ingest", st.to_string());
  print_ingest_summary(report, a.out, sw.seconds());
  return kExitOk;
}

}  // namespace

Command add_ingest_command(CLI::App& parent) {
  auto args = std::make_shared<IngestArgs>();
  CLI::App* sub = parent.add_subcommand(
      "ingest", "Turn a video file or a folder of images into a dataset: pick sharp, well-spread frames, run COLMAP");
  sub->add_option("input", args->input, "Video file (any format FFmpeg reads) or folder of PNG/JPEG images")->required();
  add_ingest_options(sub, &args->out, &args->options, true);
  return {sub, [args] { return run_ingest(*args); }};
}

}  // namespace hbgs::cli
