// SPDX-License-Identifier: MIT
// A training run's time budget: pace, fit and the predicted length (time_budget.h).
#include "time_budget.h"

#include <algorithm>
#include <cmath>

namespace gs::jobs {

TimeBudget::TimeBudget(double budget_seconds, int cap) : budget_(budget_seconds), cap_(cap) {}

void TimeBudget::record(int iteration, double seconds) {
  if (iteration <= 1 || !(seconds >= 0)) return;
  if (samples_.size() < size_t(kWindow)) samples_.push_back(seconds);
  else samples_[next_] = seconds;
  next_ = (next_ + 1) % size_t(kWindow);
  ++recorded_;
}

double TimeBudget::pace() const {
  if (samples_.empty()) return 0;
  double sum = 0;
  for (double s : samples_) sum += s;
  return sum / double(samples_.size());
}

bool TimeBudget::next_fits(double used) const { return used + pace() <= budget_ && used < budget_; }

bool TimeBudget::due(double used) const {
  if (recorded_ == 0) return false;
  if (predictions_ == 0) return recorded_ >= kFirstSamples || used >= 0.05 * budget_;
  return used >= next_due_;
}

int TimeBudget::predict(int it, double used) {
  const double p = pace();
  double total = double(cap_);
  if (p > 0) total = std::min(total, double(it) + std::floor(std::max(budget_ - used, 0.0) / p));
  ++predictions_;
  next_due_ = used + 0.02 * budget_;
  return std::max(it, int(total));
}

}  // namespace gs::jobs
