// SPDX-License-Identifier: MIT
// Private to gs_model: bounds-checked little-endian reader and appending writer for the model and
// checkpoint files (every read reports the file and byte offset where the data ran out).
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "gs/bytes.h"
#include "gs/hash.h"
#include "gs/model/hybrid_model.h"
#include "gs/random.h"
#include "gs/status.h"

namespace gs::model::detail {

class ByteWriter {
 public:
  std::vector<uint8_t> bytes;
  void u8(uint8_t v) { bytes.push_back(v); }
  void u32(uint32_t v) { bytes::append_u32(bytes, v); }
  void u64(uint64_t v) { bytes::append_u64(bytes, v); }
  void i32(int32_t v) { u32(uint32_t(v)); }
  void f32(float v) { bytes::append_f32(bytes, v); }
  void f64(double v) { bytes::append_f64(bytes, v); }
  void raw(const void* p, size_t n) {
    const uint8_t* b = static_cast<const uint8_t*>(p);
    bytes.insert(bytes.end(), b, b + n);
  }
  void floats(const float* p, size_t n) {
    for (size_t i = 0; i < n; ++i) f32(p[i]);
  }
  template <class T>
  void pod_array(const std::vector<T>& v) {  // count + elements, little-endian per element
    u64(v.size());
    for (const T& x : v) bytes::append_le(bytes, uint64_t(x), int(sizeof(T)));
  }
};

class ByteReader {
 public:
  ByteReader(const uint8_t* data, size_t size, std::string source) : p_(data), n_(size), source_(std::move(source)) {}
  size_t offset() const { return off_; }
  bool need(size_t bytes, const char* what) {
    if (!status_.ok()) return false;
    if (bytes > n_ - off_) {
      status_ = parse_error(source_ + ": truncated at byte " + std::to_string(off_) + " while reading " + what +
                            " (needs " + std::to_string(bytes) + " more bytes, file has " +
                            std::to_string(n_ - off_) + ")");
      return false;
    }
    return true;
  }
  uint8_t u8(const char* what) { return need(1, what) ? uint8_t(take(1)) : 0; }
  uint32_t u32(const char* what) { return need(4, what) ? uint32_t(take(4)) : 0; }
  uint64_t u64(const char* what) { return need(8, what) ? take(8) : 0; }
  int32_t i32(const char* what) { return int32_t(u32(what)); }
  float f32(const char* what) {
    const uint32_t b = u32(what);
    float f;
    std::memcpy(&f, &b, 4);
    return f;
  }
  double f64(const char* what) {
    const uint64_t b = u64(what);
    double d;
    std::memcpy(&d, &b, 8);
    return d;
  }
  bool floats(float* dst, size_t count, const char* what) {
    if (!status_.ok()) return false;
    if (count > (n_ - off_) / 4) {  // also guards 4 * count against overflow
      need(n_ - off_ + 1, what);
      return false;
    }
    for (size_t i = 0; i < count; ++i) dst[i] = bytes::load_f32(p_ + off_ + 4 * i);
    off_ += 4 * count;
    return true;
  }
  bool bytes(void* dst, size_t count, const char* what) {
    if (!need(count, what)) return false;
    std::memcpy(dst, p_ + off_, count);
    off_ += count;
    return true;
  }
  bool skip(size_t count) {
    if (!need(count, "skipped bytes")) return false;
    off_ += count;
    return true;
  }
  template <class T>
  bool pod_array(std::vector<T>* v, uint64_t max_count, const char* what) {
    const uint64_t count = u64(what);
    if (!status_.ok()) return false;
    if (count > max_count || count > (n_ - off_) / sizeof(T)) return fail(std::string(what) + ": count " + std::to_string(count) + " is impossible");
    v->resize(size_t(count));
    for (auto& x : *v) x = T(take(int(sizeof(T))));
    return true;
  }
  bool fail(const std::string& message) {
    if (status_.ok()) status_ = parse_error(source_ + ": at byte " + std::to_string(off_) + ": " + message);
    return false;
  }
  const Status& status() const { return status_; }

 private:
  uint64_t take(int bytes) {
    const uint64_t v = bytes::load_le(p_ + off_, bytes);
    off_ += size_t(bytes);
    return v;
  }
  const uint8_t* p_;
  size_t n_, off_ = 0;
  std::string source_;
  Status status_;
};

using gs::fnv1a64;  // gs/hash.h: detects corruption of model and checkpoint files

using SplitMix64 = gs::SplitMix64;  // gs/random.h

// The model configuration as the model file and the compact file both store it (the same fields
// in the same order), then the voxel size and scene extent of the model.
inline void write_model_header(ByteWriter* w, const ModelConfig& c, float voxel_size, float scene_extent) {
  w->i32(c.k);
  w->i32(c.feature_dim);
  w->i32(c.hidden);
  w->i32(int32_t(c.image_features));
  w->i32(c.image_feature_dim);
  w->i32(c.image_feature_hidden);
  w->u64(c.max_anchors);
  w->u64(c.max_gaussians);
  w->f32(c.voxel_size);
  w->f32(voxel_size);
  w->f32(scene_extent);
}
inline void read_model_header(ByteReader* r, ModelConfig* c, float* voxel_size, float* scene_extent) {
  c->k = r->i32("k");
  c->feature_dim = r->i32("the feature dimension");
  c->hidden = r->i32("the hidden width");
  c->image_features = ImageFeatureMode(r->i32("the image feature mode"));
  c->image_feature_dim = r->i32("the image feature dimension");
  c->image_feature_hidden = r->i32("the image feature hidden width");
  c->max_anchors = size_t(r->u64("the anchor budget"));
  c->max_gaussians = size_t(r->u64("the Gaussian budget"));
  c->voxel_size = r->f32("the configured voxel size");
  *voxel_size = r->f32("the voxel size");
  *scene_extent = r->f32("the scene extent");
}

// The scene frame (gs/scene_frame.h) as the model, compact and checkpoint files store it: the centre
// and the scale as f64; read_scene_frame checks it.
inline void write_scene_frame(ByteWriter* w, const SceneFrame& f) {
  for (double c : f.centre) w->f64(c);
  w->f64(f.scale);
}
inline bool read_scene_frame(ByteReader* r, SceneFrame* f) {
  for (double& c : f->centre) c = r->f64("the scene frame");
  f->scale = r->f64("the scene frame");
  return r->status().ok() && *scene_frame_problem(*f) == 0;
}
inline constexpr size_t kSceneFrameBytes = 32;

}  // namespace gs::model::detail
