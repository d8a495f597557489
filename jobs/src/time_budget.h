// SPDX-License-Identifier: MIT
// Private to the training job: a time budget's bookkeeping (TrainRunOptions::time_budget). It
// measures the pace of the steps, says whether the next one fits, and predicts how many iterations
// the run will hold, for the job to re-target the schedule to.
#pragma once

#include <cstddef>
#include <vector>

namespace gs::jobs {

class TimeBudget {
 public:
  // budget: seconds of training in all (a resumed run has spent some: `used` below counts them);
  // cap: the most iterations the run may have.
  TimeBudget(double budget_seconds, int cap);

  // One step's training seconds, in order (a resumed run first replays those it recorded). The
  // run's first step (iteration 1) is not a pace sample: it touches every page for the first time.
  void record(int iteration, double seconds);
  // Seconds per iteration: the mean of the last kWindow samples (the occasional dear step, anchor
  // growth or a feature refresh, is part of the pace); 0 while there is no sample.
  double pace() const;
  // Whether another step fits: used + pace <= budget (while the pace is unknown: used < budget).
  bool next_fits(double used) const;
  // Whether to predict again after completed iteration `it`: first once kFirstSamples steps are
  // measured (or 5 % of the budget is spent), then every 2 % of the budget.
  bool due(double used) const;
  // The run's length from here: it + the steps that fit in what is left at the current pace, at
  // most the cap and at least it. Marks the prediction done (for due).
  int predict(int it, double used);

  double budget() const { return budget_; }
  int predictions() const { return predictions_; }

  static constexpr int kWindow = 50, kFirstSamples = 20;

 private:
  double budget_;
  int cap_;
  std::vector<double> samples_;  // the last kWindow step times (ring)
  size_t next_ = 0;
  int recorded_ = 0;
  double next_due_ = 0;  // training seconds at which to predict again (after the first prediction)
  int predictions_ = 0;
};

}  // namespace gs::jobs
