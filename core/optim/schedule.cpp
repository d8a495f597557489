// SPDX-License-Identifier: MIT
// Learning-rate schedules (see gs/optim/schedule.h).
#include "gs/optim/schedule.h"

#include <algorithm>
#include <cmath>

#include "gs/constants.h"

namespace gs::optim {

double expon_lr(double lr0, double lr1, int steps, int it) {
  return expon_lr_at(lr0, lr1, double(it) / double(std::max(steps, 1)));
}

double expon_lr_at(double lr0, double lr1, double progress) {
  if (lr0 == lr1) return lr0;
  const double t = std::min(std::max(progress, 0.0), 1.0);
  if (!(lr0 > 0 && lr1 > 0)) return (1 - t) * lr0 + t * lr1;
  return std::exp((1 - t) * std::log(lr0) + t * std::log(lr1));
}

double warmup(int steps, int it) { return steps > 0 ? std::min(1.0, double(it) / double(steps)) : 1.0; }

double cosine_decay(int steps, int it, double floor) {
  const double c = 0.5 * (1 + std::cos(kPi * double(it - 1) / double(steps)));
  return floor + (1 - floor) * c;
}

}  // namespace gs::optim
