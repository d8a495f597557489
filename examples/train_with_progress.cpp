// SPDX-License-Identifier: MIT
// Example: train the hybrid anchor model on a COLMAP dataset with the library's training job,
// printing progress from its callback. Built only against the installed hbgs (find_package).
//   train_with_progress DATASET RUN [ITERATIONS]
#include <cstdio>
#include <cstdlib>
#include <string>

#include "gs/hbgs.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s DATASET RUN [ITERATIONS]\n", argv[0]);
    return 2;
  }
  gs::jobs::TrainRunOptions options;  // every default of `hbgs train`
  options.dataset = argv[1];
  options.out = argv[2];
  options.iterations = argc > 3 ? std::atoi(argv[3]) : 300;
  options.save_at = "";  // only the final model
  options.force = true;  // replace an earlier run in RUN

  auto progress = [](const gs::jobs::TrainEvent& e) {
    if (e.kind == gs::jobs::TrainEvent::kIteration) {
      if (e.iteration % 50 == 0 || e.iteration == e.iterations)
        std::printf("iteration %d/%d: loss %.4f, %zu anchors\n", e.iteration, e.iterations, e.stats->step.loss,
                    e.stats->anchors);
    } else if (e.kind != gs::jobs::TrainEvent::kPoseErrors) {
      std::printf("%s\n", e.message.c_str());
    }
  };
  gs::jobs::TrainRunSummary summary;
  if (gs::Status st = gs::jobs::train_run(options, progress, &summary); !st.ok()) {
    std::fprintf(stderr, "train_with_progress: %s\n", st.to_string().c_str());
    return 1;
  }
  std::printf("trained %d iterations in %.1f s: test PSNR %.2f dB, model %s\n", summary.iterations, summary.train_seconds,
              summary.final_eval.psnr, summary.model_path.c_str());
  return 0;
}
