// SPDX-License-Identifier: MIT
// The trainer's checkpoint file (Trainer::save_checkpoint / load_checkpoint, gs/model/trainer.h):
// magic "HBGSCKPT", version, the model, every Adam moment, the densification statistics, the
// iteration, generator and view order, the training poses with their Adam state and the held-back
// views, the re-targeted schedule of a run whose length changed (Trainer::retarget), then an FNV-1a
// 64 checksum. Versions 2 to 4 are read.
#include <algorithm>
#include <array>
#include <cassert>
#include <cstring>
#include <string>

#include "gs/platform/file.h"
#include "trainer_state.h"

namespace gs::model {

namespace {

constexpr char kCheckpointMagic[8] = {'H', 'B', 'G', 'S', 'C', 'K', 'P', 'T'};
// 2: training poses and their Adam state; 3: held-back views; 4: the re-targeted schedule;
// 5: the views released by registration (polished again while the held-back window lasts).
constexpr uint32_t kCheckpointVersion = 5;

// The schedule fields Trainer::retarget changes, in the order the checkpoint stores them.
template <class Opt>
auto schedule_fields(Opt& o) {
  return std::array<decltype(&o.iterations), 12>{&o.iterations, &o.schedule_iterations, &o.stat_start, &o.update_from,
                                                 &o.update_interval, &o.update_until, &o.pose_warmup, &o.pose_register_every,
                                                 &o.pose_register_until, &o.held_back_register_every,
                                                 &o.held_back_register_from, &o.held_back_register_until};
}

}  // namespace

Status Trainer::save_checkpoint(const std::string& path) const {
  const Impl& d = *impl_;
  if (Status st = check_model_finite(d.model, path); !st.ok()) return Status(st.code(), "refusing to write " + st.message());
  const size_t M = d.model.anchor_count, K = size_t(d.model.config.k), nv = d.views.size();
  // The file is built in one buffer of its exact size (no growth doubling, no second copy of the
  // model): it is written at the end of a run, when training memory peaks.
  const size_t model_size = serialized_model_size(d.model);
  size_t size = 8 + 4 + 8 + model_size + 8 + 4 + 8 + 8 + 4 * nv + 8;
  for (const detail::ParamGroup& g : d.groups) size += 2 * 4 * g.live(M);
  size += 8 * M + 8 * M * K + nv * (12 * 4 + 4 + 12 * 8) + nv + 1 + (d.retargeted ? 12 * 4 + 16 : 0) + 8;
  detail::ByteWriter w;
  w.bytes.reserve(size);
  for (char ch : kCheckpointMagic) w.u8(uint8_t(ch));  // (w.raw after reserve: a GCC 12 false -Wstringop-overflow)
  w.u32(kCheckpointVersion);
  w.u64(model_size);
  append_serialized_model(d.model, &w.bytes);
  w.u64(d.views.size());
  w.i32(d.iteration);
  w.u64(d.rng.state);
  w.u64(d.view_pos);
  for (int32_t v : d.view_order) w.i32(v);
  w.u64(d.groups.size());
  for (const detail::ParamGroup& g : d.groups) {
    w.floats(g.m.data(), g.live(M));
    w.floats(g.v.data(), g.live(M));
  }
  w.floats(d.opacity_accum.data(), M);
  for (size_t i = 0; i < M; ++i) w.i32(d.anchor_seen[i]);
  w.floats(d.grad_accum.data(), M * K);
  for (size_t i = 0; i < M * K; ++i) w.i32(d.grad_denom[i]);
  for (size_t v = 0; v < d.views.size(); ++v) {
    w.floats(d.view_cameras[v].pose.R, 9);
    w.floats(d.view_cameras[v].pose.t, 3);
    w.i32(d.pose_steps[v]);
    for (int i = 0; i < 6; ++i) {
      w.f64(d.pose_m[6 * v + size_t(i)]);
      w.f64(d.pose_v[6 * v + size_t(i)]);
    }
  }
  for (uint8_t h : d.held) w.u8(h);
  w.u8(d.retargeted ? 1 : 0);
  if (d.retargeted) {
    for (const int* f : schedule_fields(d.opt)) w.i32(*f);
    w.f64(d.lr_progress);
    w.f64(d.coarse_end);
  }
  for (uint8_t r : d.repaired) w.u8(r);
  w.u64(detail::fnv1a64(w.bytes.data(), w.bytes.size()));
  assert(w.bytes.size() == size);  // the plan above matches what was written
  return platform::write_file_atomic(path, w.bytes.data(), w.bytes.size());
}

Status Trainer::load_checkpoint(const std::string& path) {
  Impl& d = *impl_;
  Expected<std::vector<uint8_t>> file = platform::read_file(path);
  if (!file.ok()) return file.status();
  const std::vector<uint8_t>& bytes = *file;
  detail::ByteReader r(bytes.data(), bytes.size(), path);
  char magic[8] = {};
  if (!r.bytes(magic, 8, "the file signature")) return r.status();
  if (std::memcmp(magic, kCheckpointMagic, 8) != 0) return parse_error(path + ": not an hbgs checkpoint");
  const uint32_t version = r.u32("the format version");
  if (!r.status().ok()) return r.status();
  if (version > kCheckpointVersion || version < 2)
    return unsupported(path + ": checkpoint format version " + std::to_string(version) + ", this hbgs reads versions 2 to " +
                       std::to_string(kCheckpointVersion) + (version == 1 ? " (version 1 predates pose optimisation; restart the run)" : ""));
  if (bytes.size() < 8 || detail::fnv1a64(bytes.data(), bytes.size() - 8) != bytes::load_u64(bytes.data() + bytes.size() - 8))
    return parse_error(path + ": checksum mismatch (the checkpoint is truncated or corrupt)");
  const uint64_t model_size = r.u64("the model size");
  if (!r.status().ok()) return r.status();
  if (model_size > bytes.size() - r.offset()) return parse_error(path + ": the embedded model is larger than the file");
  Expected<HybridModel> model = deserialize_model(bytes.data() + r.offset(), size_t(model_size), path + " (model)");
  if (!model.ok()) return model.status();
  r.skip(size_t(model_size));
  const ModelConfig& a = model->config;
  const ModelConfig& b = d.model.config;
  if (a.k != b.k || a.feature_dim != b.feature_dim || a.hidden != b.hidden || a.image_features != b.image_features ||
      a.image_feature_dim != b.image_feature_dim || a.image_feature_hidden != b.image_feature_hidden ||
      a.max_anchors != b.max_anchors || a.max_gaussians != b.max_gaussians)
    return invalid_argument(path + ": the checkpoint's model configuration differs from this run's");
  if (model->frame != d.model.frame)
    return invalid_argument(path + ": the checkpoint's scene frame differs from this run's (the dataset's cameras changed)");
  const uint64_t nviews = r.u64("the view count");
  if (r.status().ok() && nviews != d.views.size())
    return invalid_argument(path + ": the checkpoint was trained on " + std::to_string(nviews) +
                            " views, this dataset has " + std::to_string(d.views.size()) + " training views");
  const int iteration = r.i32("the iteration");
  const uint64_t rng_state = r.u64("the generator state");
  const uint64_t view_pos = r.u64("the view position");
  std::vector<int32_t> order(d.views.size());
  for (int32_t& v : order) {
    v = r.i32("the view order");
    if (r.status().ok() && (v < 0 || size_t(v) >= d.views.size())) return parse_error(path + ": bad view index");
  }
  const uint64_t ngroups = r.u64("the group count");
  if (!r.status().ok()) return r.status();
  if (ngroups != d.groups.size() || view_pos > order.size() || iteration < 0)
    return parse_error(path + ": inconsistent optimiser state");
  // Everything is checked: adopt the model into the planned arrays (grown first if the checkpoint
  // holds more anchors than this trainer has rows).
  HybridModel& m = d.model;
  const size_t M = model->anchor_count, K = size_t(a.k);
  if (M > d.budget()) return parse_error(path + ": the checkpoint holds more anchors than the budget");
  GS_RETURN_IF_ERROR(d.ensure_capacity(M));
  auto adopt = [](std::vector<float>& dst, const std::vector<float>& src, size_t n) { std::copy(src.begin(), src.begin() + std::ptrdiff_t(n), dst.begin()); };
  adopt(m.positions, model->positions, M * 3);
  adopt(m.offsets, model->offsets, M * K * 3);
  adopt(m.log_scales, model->log_scales, M * 6);
  adopt(m.features, model->features, M * size_t(a.feature_dim));
  if (d.paper()) adopt(m.image_raw, model->image_raw, M * size_t(kImageRawDim));
  for (int i = 0; i < kMlpCount; ++i) adopt(m.mlps[i].params, model->mlps[i].params, model->mlps[i].params.size());
  m.anchor_count = M;
  m.voxel_size = model->voxel_size;
  m.scene_extent = model->scene_extent;
  for (detail::ParamGroup& g : d.groups) {
    r.floats(g.m.data(), g.live(M), "Adam moments");
    r.floats(g.v.data(), g.live(M), "Adam moments");
  }
  r.floats(d.opacity_accum.data(), M, "statistics");
  for (size_t i = 0; i < M; ++i) d.anchor_seen[i] = r.i32("statistics");
  r.floats(d.grad_accum.data(), M * K, "statistics");
  for (size_t i = 0; i < M * K; ++i) d.grad_denom[i] = r.i32("statistics");
  for (size_t v = 0; v < d.views.size(); ++v) {
    r.floats(d.view_cameras[v].pose.R, 9, "training poses");
    r.floats(d.view_cameras[v].pose.t, 3, "training poses");
    d.pose_steps[v] = r.i32("training poses");
    for (int i = 0; i < 6; ++i) {
      d.pose_m[6 * v + size_t(i)] = r.f64("pose moments");
      d.pose_v[6 * v + size_t(i)] = r.f64("pose moments");
    }
  }
  std::vector<uint8_t> held(d.views.size(), 0);  // version 2 predates held-back views: none
  if (version >= 3)
    for (uint8_t& h : held) {
      h = r.u8("held-back views");
      if (r.status().ok() && h > 1) return parse_error(path + ": bad held-back flag");
    }
  TrainOptions schedule = d.opt;  // version 3 and before, or never re-targeted: the options as created
  bool retargeted = false;
  double lr_progress = 0, coarse_end = d.coarse_end;
  if (version >= 4) {
    const uint8_t flag = r.u8("the schedule flag");
    if (r.status().ok() && flag > 1) return parse_error(path + ": bad schedule flag");
    retargeted = flag == 1;
    if (retargeted) {
      for (int* f : schedule_fields(schedule)) *f = r.i32("the schedule");
      lr_progress = r.f64("the schedule");
      coarse_end = r.f64("the schedule");
      if (r.status().ok() && (schedule.schedule_iterations < 1 || schedule.update_interval < 1 || schedule.iterations < 0 ||
                              schedule.pose_warmup < 0 || schedule.pose_register_every < 0 || schedule.held_back_register_every < 0 ||
                              !(lr_progress >= 0 && lr_progress <= 1) || !(coarse_end >= 0)))
        return parse_error(path + ": bad schedule");
    }
  }
  std::vector<uint8_t> repaired(d.views.size(), 0);  // version 4 and before: none recorded
  if (version >= 5)
    for (size_t v = 0; v < repaired.size(); ++v) {
      repaired[v] = r.u8("released views");
      if (r.status().ok() && (repaired[v] > 1 || (repaired[v] && held[v]))) return parse_error(path + ": bad released-view flag");
    }
  if (!r.status().ok()) return r.status();
  if (std::find(held.begin(), held.end(), uint8_t(0)) == held.end()) return parse_error(path + ": every view is held back");
  if (retargeted) {
    for (size_t i = 0; i < schedule_fields(d.opt).size(); ++i) *schedule_fields(d.opt)[i] = *schedule_fields(schedule)[i];
    d.lr_progress = lr_progress;
    d.coarse_end = coarse_end;
    d.retargeted = true;
  }
  d.held = held;
  d.repaired = repaired;
  d.iteration = iteration;
  d.rng.state = rng_state;
  d.view_pos = size_t(view_pos);
  d.view_order = order;
  return Status::Ok();
}

}  // namespace gs::model
