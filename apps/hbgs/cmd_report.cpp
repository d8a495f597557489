// SPDX-License-Identifier: MIT
// `hbgs report RUN`: writes the run's report page (gs/jobs/report.h), one self-contained HTML file
// with the metrics, the PSNR-vs-time plot, test renders beside ground truth and a WebGL viewer of
// the baked model, then prints what it holds.
#include <cstdio>
#include <memory>
#include <string>

#include "common.h"
#include "gs/jobs/report.h"

namespace hbgs::cli {

int run_report(const gs::jobs::ReportRunOptions& a) {
  gs::jobs::ReportRunSummary s;
  if (gs::Status st = gs::jobs::report_run(a, &s); !st.ok())
    return fail("report", st.code() == gs::StatusCode::kInvalidArgument ? st.message() : st.to_string());
  std::printf("hbgs report: %s (%.2f MB, %.1f s)\n", s.path.c_str(), double(s.bytes) / 1e6, s.seconds);
  std::printf("  viewer: %zu splats", s.splats);
  if (s.splats < s.baked) std::printf(" of %zu baked (capped by --max-splats)", s.baked);
  std::printf(", %.2f MB as .splat; %zu dataset cameras\n", double(s.splat_bytes) / 1e6, s.cameras);
  std::printf("  test PSNR of the viewer's splats rendered by hbgs: %.2f dB", s.splats_psnr);
  if (s.model_psnr >= 0) std::printf(" (the model at iteration %d: %.2f dB)", s.iteration, s.model_psnr);
  std::printf("\n  renders beside ground truth: %zu of %zu test views", s.shown_views.size(), s.test_views);
  for (size_t k = 0; k < s.shown_views.size(); ++k) std::printf("%s%s", k ? ", " : ": ", s.shown_views[k].c_str());
  std::printf("\n");
  return kExitOk;
}

Command add_report_command(CLI::App& parent) {
  auto a = std::make_shared<gs::jobs::ReportRunOptions>();
  CLI::App* sub = parent.add_subcommand(
      "report", "Write RUN/report.html: metrics, PSNR-vs-time plot, test renders beside ground truth and a WebGL viewer of the "
                "baked model, in one file that works offline");
  sub->add_option("run", a->run, "Run folder (from hbgs train)")->required();
  sub->add_option("--out", a->out, "The page to write (default: RUN/report.html)");
  sub->add_option("--max-splats", a->max_splats,
                  "Most splats the viewer gets (32 bytes each, 4/3 of that in the page); the largest contributions are kept")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000000));
  sub->add_option("--distill", a->distill_iterations,
                  "Steps fitting the baked Gaussians to the model's renders of the training views (0: the least-squares fit only)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000000));
  sub->add_option("--views", a->views, "Test views shown as render beside ground truth (spread over the split)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  sub->add_option("--dataset", a->dataset, "The run's dataset, if it moved (default: the one recorded in run.json)");
  sub->add_option("--threads", a->threads, "Worker threads (0: all CPUs)")->capture_default_str()->check(CLI::Range(0, 4096));
  return {sub, [a] { return run_report(*a); }};
}

}  // namespace hbgs::cli
