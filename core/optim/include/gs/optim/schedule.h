// SPDX-License-Identifier: MIT
// Learning-rate schedules of the optimiser (gs/optim/adam.h): the reference code's log-linear
// decay, the pose warm-up, and registration's per-level cosine decay.
#pragma once

namespace gs::optim {

// expon(lr0, lr1, steps)(it): log-linear from lr0 to lr1 over `steps`, then held (ALGORITHM.md
// Part B section 6). A zero or negative end makes it linear (log(0) is -inf, and 0 x -inf is NaN).
double expon_lr(double lr0, double lr1, int steps, int it);
// The same schedule at a progress fraction t of its horizon (clamped to [0, 1]): expon_lr(lr0, lr1,
// steps, it) is expon_lr_at(lr0, lr1, it / steps). A run whose length changes while it trains (a
// time budget) keeps its rates monotone by never letting t decrease.
double expon_lr_at(double lr0, double lr1, double t);

// Linear warm-up factor min(1, it / steps); 1 when steps <= 0.
double warmup(int steps, int it);

// Cosine decay from 1 at it = 1 to floor near it = steps + 1: floor + (1 - floor) x
// (1 + cos(pi (it - 1) / steps)) / 2 (large early steps, fine ones at the end).
double cosine_decay(int steps, int it, double floor);

}  // namespace gs::optim
