// SPDX-License-Identifier: MIT
// Live tracking against a model (gs/model/tracker.h). Work in progress: create() refuses until the
// tracker lands (issue 25).
#include "gs/model/tracker.h"

namespace gs::pose {

const char* track_verdict_name(TrackVerdict v) {
  switch (v) {
    case TrackVerdict::kTracking: return "tracking";
    case TrackVerdict::kRelocalized: return "relocalized";
    case TrackVerdict::kLost: return "lost";
  }
  return "?";
}

struct Tracker::Impl {
  TrackOptions opt;
};

Tracker::Tracker() : impl_(new Impl) {}
Tracker::~Tracker() = default;

Expected<std::unique_ptr<Tracker>> Tracker::create(const model::HybridModel&, const PinholeIntrinsics&, const TrackOptions&,
                                                   platform::ThreadPool*, const simd::KernelTable*) {
  return Status(StatusCode::kUnsupported, "the tracker is not built yet");
}
Status Tracker::set_candidates(const std::vector<Pose>&) { return Status(StatusCode::kUnsupported, "not built yet"); }
void Tracker::reset(const Pose&) {}
void Tracker::reset() {}
Status Tracker::track(const uint8_t*, double, TrackResult*) { return Status(StatusCode::kUnsupported, "not built yet"); }
const TrackOptions& Tracker::options() const { return impl_->opt; }
uint64_t Tracker::planned_bytes() const { return 0; }

}  // namespace gs::pose
