// SPDX-License-Identifier: MIT
// Live tracking against a model (gs/model/tracker.h): keyframes rendered at full resolution and
// box-filtered to the tracking pyramid, direct alignment of each frame to the current keyframe,
// a verdict per frame, and relocalisation from described candidate poses.
#include "gs/model/tracker.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "gs/io/image.h"
#include "gs/constants.h"
#include "gs/platform/clock.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "pose_solve.h"
#include "image_descriptor.h"

namespace gs::pose {

const char* track_verdict_name(TrackVerdict v) {
  switch (v) {
    case TrackVerdict::kTracking: return "tracking";
    case TrackVerdict::kRelocalized: return "relocalized";
    case TrackVerdict::kLost: return "lost";
  }
  return "?";
}

namespace {

constexpr size_t kChunk = 256;          // keyframe points per partial sum (fixed: sums do not depend on threads)
constexpr size_t kKeyframeRing = 16;    // recent keyframes kept as relocalisation candidates
constexpr double kMinInside = 0.5;      // a frame whose keyframe points mostly leave it is not tracked
// No RMSE up to this is suspicious, however small the stream's usual one (a model's own renders:
// 0.001; real photos against a good model: 0.012-0.02).
constexpr double kRmseFloor = 0.03;

// Sums of one chunk of keyframe points (or of all): the upper triangle of J^T W J, J^T W r, the
// Huber cost, the squared colour residual and the counts.
struct Sums {
  double A[21], b[6], cost, se, sum, sq;  // sum, sq: of the frame's colour values at the points inside
  uint32_t used, inside;
  void clear() { std::memset(this, 0, sizeof(*this)); }
  void add(const Sums& o) {
    for (int i = 0; i < 21; ++i) A[i] += o.A[i];
    for (int i = 0; i < 6; ++i) b[i] += o.b[i];
    cost += o.cost, se += o.se, sum += o.sum, sq += o.sq, used += o.used, inside += o.inside;
  }
};

// Keyframe points of one pyramid level: camera coordinates and colour of every covered pixel.
struct KeyLevel {
  PinholeIntrinsics in;
  std::vector<float> xyz, rgb;  // [n, 3] each
  size_t n = 0;
};

struct FrameLevel {
  PinholeIntrinsics in;
  std::vector<float> rgb;  // [h, w, 3] in [0, 1]
};

// The pose mapping camera `from`'s coordinates to camera `to`'s: to from^-1.
Pose relative(const Pose& to, const Pose& from) {
  double R[9], t[3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += double(to.R[3 * i + k]) * double(from.R[3 * j + k]);
      R[3 * i + j] = s;
    }
  for (int i = 0; i < 3; ++i)
    t[i] = double(to.t[i]) - (R[3 * i] * from.t[0] + R[3 * i + 1] * from.t[1] + R[3 * i + 2] * from.t[2]);
  Pose p;
  for (int i = 0; i < 9; ++i) p.R[i] = float(R[i]);
  for (int i = 0; i < 3; ++i) p.t[i] = float(t[i]);
  return p;
}

// rel applied after base: (R_rel R_base, R_rel t_base + t_rel).
Pose compose(const Pose& rel, const Pose& base) {
  Pose p;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double s = 0;
      for (int k = 0; k < 3; ++k) s += double(rel.R[3 * i + k]) * double(base.R[3 * k + j]);
      p.R[3 * i + j] = float(s);
    }
    double s = rel.t[i];
    for (int k = 0; k < 3; ++k) s += double(rel.R[3 * i + k]) * double(base.t[k]);
    p.t[i] = float(s);
  }
  return p;
}


// v (RGB) -> (sqrt(3) Y, w (B - Y), w (R - Y)) in place (see Impl::evaluate).
inline void to_luma_chroma(float v[3], float w) {
  const float y = 0.299f * v[0] + 0.587f * v[1] + 0.114f * v[2];
  const float cb = v[2] - y, cr = v[0] - y;
  v[0] = 1.7320508f * y, v[1] = w * cb, v[2] = w * cr;
}

}  // namespace

struct Tracker::Impl {
  TrackOptions opt;
  platform::ThreadPool* pool = nullptr;
  PinholeIntrinsics full;
  int levels = 1;
  double extent = 1;
  std::unique_ptr<Registrar> registrar;
  std::vector<float> key_rgb, key_alpha, key_depth;  // the keyframe render, full resolution
  std::vector<float> lvl_rgb, lvl_alpha, lvl_depth;  // its box-filtered level (scratch)
  std::vector<KeyLevel> key;
  std::vector<FrameLevel> frame;
  std::vector<Sums> partial;
  Pose key_pose;
  double key_rmse = -1;
  bool have_key = false;
  uint64_t keyframes = 0;
  // Motion: the last two tracked poses and times; `placed` while the previous frame had a pose.
  Pose last[2];
  double last_time[2] = {0, 0};
  int history = 0;
  bool placed = false, have_start = false;
  Pose start;
  double previous_time = -std::numeric_limits<double>::infinity();
  // Relocalisation: candidate poses and descriptors (the given set, then a ring of keyframes).
  size_t desc_dim = 0;
  std::vector<Pose> cand;
  std::vector<float> cand_desc;
  Pose ring[kKeyframeRing];
  std::vector<float> ring_desc;  // [kKeyframeRing, desc_dim]
  size_t ring_count = 0, ring_next = 0;
  std::vector<float> frame_desc, key_desc;
  std::vector<std::pair<float, int>> ranked;  // (1 - NCC, index: >= 0 candidate, < 0 ring slot -1 - i)
  uint64_t bytes = 0;

  Camera camera(const Pose& p) const { return Camera{full, p}; }
  int factor(int level) const { return opt.track_downscale << level; }

  // Renders the keyframe at pose p and builds its points at every level; its coarsest level's
  // descriptor goes into the ring.
  Status render_keyframe(const Pose& p) {
    GS_RETURN_IF_ERROR(registrar->render(camera(p), key_rgb.data(), key_depth.data(), key_alpha.data()));
    for (int l = 0; l < levels; ++l) {
      KeyLevel& k = key[size_t(l)];
      const int f = factor(l), w = k.in.width, h = k.in.height;
      io::box_downsample_float(key_rgb.data(), full.width, full.height, 3, f, lvl_rgb.data());
      io::box_downsample_float(key_alpha.data(), full.width, full.height, 1, f, lvl_alpha.data());
      io::box_downsample_float(key_depth.data(), full.width, full.height, 1, f, lvl_depth.data());
      size_t n = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          const size_t pix = size_t(y) * size_t(w) + size_t(x);
          const float a = lvl_alpha[pix];
          if (!(a > 0.5f)) continue;
          const float z = lvl_depth[pix] / a;
          if (!(z > 1e-3f) || !std::isfinite(z)) continue;
          k.xyz[3 * n] = z * ((float(x) + 0.5f) - k.in.cx) / k.in.fx;
          k.xyz[3 * n + 1] = z * ((float(y) + 0.5f) - k.in.cy) / k.in.fy;
          k.xyz[3 * n + 2] = z;
          for (int c = 0; c < 3; ++c) k.rgb[3 * n + size_t(c)] = lvl_rgb[3 * pix + size_t(c)];
          ++n;
        }
      k.n = n;
      if (l == levels - 1) detail::grey_descriptor(lvl_rgb.data(), size_t(w) * size_t(h), key_desc.data());  // lvl_rgb: the coarsest level
    }
    key_pose = p;
    key_rmse = -1;  // set by the next frame's alignment (its own frame's residual is the model's alone)
    have_key = true;
    ++keyframes;
    return Status::Ok();
  }

  // The registrar plans the Gaussians it keeps at its first decode: one registration from pose p
  // (of the model's own render there) at the first call that may allocate, so track() never does.
  bool registrar_warm = false;
  Status warm_registrar(const Pose& p) {
    if (registrar_warm) return Status::Ok();
    GS_RETURN_IF_ERROR(registrar->render(camera(p), key_rgb.data()));
    const io::Image8 img = io::image_from_float_rgb(key_rgb.data(), full.width, full.height);
    RegisterResult rr;
    GS_RETURN_IF_ERROR(registrar->register_view(img.pixels.data(), full, p, &rr));
    registrar_warm = true;
    have_key = false;  // the keyframe buffers held the render
    return Status::Ok();
  }

  // The keyframe joins the relocalisation candidates (once a frame was placed with it).
  void keep_keyframe() {
    std::copy(key_desc.begin(), key_desc.end(), ring_desc.begin() + std::ptrdiff_t(ring_next * desc_dim));
    ring[ring_next] = key_pose;
    ring_next = (ring_next + 1) % kKeyframeRing;
    ring_count = std::min(ring_count + 1, kKeyframeRing);
  }

  // The frame's pyramid (each level box-filtered from the full frame).
  void prepare(const uint8_t* rgb) {
    for (int l = 0; l < levels; ++l) io::box_downsample_rgb(rgb, full.width, full.height, factor(l), frame[size_t(l)].rgb.data());
  }

  // The keyframe's level-l points warped by rel (keyframe camera -> frame camera) into the frame:
  // Huber cost, squared residual, counts and, with jacobian, the normal equations. A point that
  // leaves the frame costs a full-delta residual (as in registration), so leaving is not free.
  void evaluate(int l, const Pose& rel, bool jacobian, double delta, Sums* total) {
    const KeyLevel& k = key[size_t(l)];
    const FrameLevel& fr = frame[size_t(l)];
    const size_t chunks = (k.n + kChunk - 1) / kChunk;
    const float fx = fr.in.fx, fy = fr.in.fy, cx = fr.in.cx, cy = fr.in.cy;
    const int w = fr.in.width, h = fr.in.height;
    const double out_cost = detail::huber_cost(2 * delta, delta);
    const float chroma = float(opt.chroma_weight);
    auto body = [&](size_t cb, size_t ce, int) {
      for (size_t c = cb; c < ce; ++c) {
        Sums s;
        s.clear();
        float fA[21] = {}, fb[6] = {};
        const size_t end = std::min(k.n, (c + 1) * kChunk);
        for (size_t i = c * kChunk; i < end; ++i) {
          const float* X = k.xyz.data() + 3 * i;
          float m[3];
          for (int r = 0; r < 3; ++r) m[r] = rel.R[3 * r] * X[0] + rel.R[3 * r + 1] * X[1] + rel.R[3 * r + 2] * X[2] + rel.t[r];
          ++s.used;
          if (!(m[2] > 1e-3f)) {
            s.cost += out_cost;
            continue;
          }
          const float iz = 1.0f / m[2];
          const float u = fx * m[0] * iz + cx - 0.5f, v = fy * m[1] * iz + cy - 0.5f;  // continuous pixel, centres at integers
          const float x0f = std::floor(u), y0f = std::floor(v);
          if (!(x0f >= 0 && y0f >= 0 && x0f + 1 < float(w) && y0f + 1 < float(h))) {
            s.cost += out_cost;
            continue;
          }
          const int x0 = int(x0f), y0 = int(y0f);
          const float ax = u - x0f, ay = v - y0f;
          const float* p00 = fr.rgb.data() + (size_t(y0) * size_t(w) + size_t(x0)) * 3;
          const float* p10 = p00 + 3;
          const float* p01 = p00 + size_t(w) * 3;
          const float* p11 = p01 + 3;
          float r[3], cu[3], cv[3];
          for (int q = 0; q < 3; ++q) {
            const float top = p00[q] + ax * (p10[q] - p00[q]), bottom = p01[q] + ax * (p11[q] - p01[q]);
            const float value = top + ay * (bottom - top);
            s.sum += value, s.sq += double(value) * value;
            r[q] = value - k.rgb[3 * i + size_t(q)];
            cu[q] = (p10[q] - p00[q]) + ay * ((p11[q] - p01[q]) - (p10[q] - p00[q]));
            cv[q] = bottom - top;
          }
          // The verdict's squared residual in RGB; the cost and the normal equations weigh the
          // residual as (sqrt(3) Y, w (B - Y), w (R - Y)), Y = 0.299 R + 0.587 G + 0.114 B,
          // w = chroma_weight: a grey residual keeps its RGB norm (and the Huber delta its scale),
          // and colour, which video codecs and Bayer sensors carry at lower resolution than
          // brightness, can count for less.
          const double se = double(r[0]) * r[0] + double(r[1]) * r[1] + double(r[2]) * r[2];
          ++s.inside;
          s.se += se;
          if (chroma >= 0) to_luma_chroma(r, chroma), to_luma_chroma(cu, chroma), to_luma_chroma(cv, chroma);
          const double rn = std::sqrt(double(r[0]) * r[0] + double(r[1]) * r[1] + double(r[2]) * r[2]);
          s.cost += detail::huber_cost(rn, delta);
          if (!jacobian) continue;
          // J_q = cu_q du + cv_q dv per channel q, so sum_q J_q J_q^T = guu du du^T + guv (du dv^T +
          // dv du^T) + gvv dv dv^T and sum_q J_q r_q = bu du + bv dv: the colour channels fold into
          // five scalars before the 6 x 6 sums (float within a chunk, double across chunks).
          const float wgt = float(detail::huber_weight(rn, delta));
          const float guu = wgt * (cu[0] * cu[0] + cu[1] * cu[1] + cu[2] * cu[2]);
          const float guv = wgt * (cu[0] * cv[0] + cu[1] * cv[1] + cu[2] * cv[2]);
          const float gvv = wgt * (cv[0] * cv[0] + cv[1] * cv[1] + cv[2] * cv[2]);
          const float bu = wgt * (cu[0] * r[0] + cu[1] * r[1] + cu[2] * r[2]);
          const float bv = wgt * (cv[0] * r[0] + cv[1] * r[1] + cv[2] * r[2]);
          // d(u, v) / d(left twist) of the projection (detail::projection_twist_jacobian in float).
          const float x = m[0], y = m[1], iz2 = iz * iz;
          const float du[6] = {fx * iz, 0.0f, -fx * x * iz2, -fx * x * y * iz2, fx * (1.0f + x * x * iz2), -fx * y * iz};
          const float dv[6] = {0.0f, fy * iz, -fy * y * iz2, -fy * (1.0f + y * y * iz2), fy * x * y * iz2, fy * x * iz};
          for (int a = 0, e = 0; a < 6; ++a) {
            fb[a] += du[a] * bu + dv[a] * bv;
            const float ua = guu * du[a] + guv * dv[a], va = guv * du[a] + gvv * dv[a];
            for (int b = a; b < 6; ++b, ++e) fA[e] += ua * du[b] + va * dv[b];
          }
        }
        for (int e = 0; e < 21; ++e) s.A[e] = fA[e];
        for (int a = 0; a < 6; ++a) s.b[a] = fb[a];
        partial[c] = s;
      }
    };
    if (pool && chunks > 1)
      pool->parallel_for(chunks, 1, body);
    else
      body(0, chunks, 0);
    total->clear();
    for (size_t c = 0; c < chunks; ++c) total->add(partial[c]);
  }

  static double mean_cost(const Sums& s) { return s.used ? s.cost / double(s.used) : INFINITY; }

  // Levenberg-Marquardt on the left twist of rel at level l; returns the final sums at rel. Every
  // trial is evaluated with its normal equations, so an accepted trial needs no second pass.
  Sums align_level(int l, Pose* rel, int* iterations, double delta) {
    Sums s;
    evaluate(l, *rel, true, delta, &s);
    double c = mean_cost(s);
    if (!std::isfinite(c)) return s;
    double lambda = 1e-3;
    for (int it = 0; it < opt.iterations_per_level; ++it) {
      detail::Mat6 A;
      detail::Vec6 b;
      for (int a = 0, e = 0; a < 6; ++a)
        for (int bb = a; bb < 6; ++bb, ++e) A(a, bb) = A(bb, a) = s.A[e];
      for (int a = 0; a < 6; ++a) b(a) = s.b[a];
      bool accepted = false;
      for (int attempt = 0; attempt < 5 && !accepted; ++attempt) {
        double xi[6];
        detail::damped_step(A, b, lambda, 0.1, 0.1 * extent, xi);
        Pose trial = *rel;
        apply_left_twist(xi, &trial);
        Sums st;
        evaluate(l, trial, true, delta, &st);
        ++*iterations;
        const double ct = mean_cost(st);
        if (ct < c) {
          const double decrease = (c - ct) / std::max(c, 1e-30);
          *rel = trial;
          s = st;
          c = ct;
          lambda = std::max(lambda / 3, 1e-7);
          accepted = true;
          const double rot = std::sqrt(xi[3] * xi[3] + xi[4] * xi[4] + xi[5] * xi[5]);
          const double tr = std::sqrt(xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2]);
          if ((rot < 2e-5 && tr < 2e-5 * extent) || decrease < 1e-5) return s;
        } else {
          lambda *= 4;
        }
      }
      if (!accepted) break;
    }
    return s;
  }

  // Aligns the prepared frame to the keyframe from pose p (coarse to fine); the pose and the
  // finest level's sums come back.
  Sums align(Pose* p, int* iterations) {
    Pose rel = relative(*p, key_pose);
    Sums s;
    s.clear();
    for (int l = levels - 1; l >= 0; --l) s = align_level(l, &rel, iterations, opt.huber_delta);
    *p = compose(rel, key_pose);
    return s;
  }

  // The verdict's figures. The explained variance is measured against the frame's own variance
  // where the keyframe's points land, not over the whole frame: against the whole frame, an object
  // on a plain background is largely "explained" by any pose that overlays its silhouette (a pose
  // 127 degrees off explained 0.82 of the test object's frame).
  void fill_stats(const Sums& s, TrackResult* out) const {
    const FrameLevel& f = frame[0];
    const double n = 3.0 * double(s.inside);
    const double mse = s.inside ? s.se / n : INFINITY;
    const double variance = s.inside ? std::max(s.sq / n - (s.sum / n) * (s.sum / n), 0.0) : 0.0;
    out->rmse = std::sqrt(mse);
    out->explained = variance > 0 && std::isfinite(mse) ? 1.0 - mse / variance : 0.0;
    out->coverage = double(s.inside) / (double(f.in.width) * double(f.in.height));
  }

  bool good(const Sums& s, const TrackResult& r) const { return fits(s, r) && usual_rmse(r.rmse); }
  // The verdict's absolute bounds: RMSE, explained variance, coverage, points inside.
  bool fits(const Sums& s, const TrackResult& r) const {
    return s.used > 0 && double(s.inside) >= kMinInside * double(s.used) && r.rmse <= opt.max_rmse &&
           r.explained >= opt.min_explained && r.coverage >= opt.min_coverage;
  }
  // The bound relative to the stream's recent residual (max_rmse_growth).
  bool usual_rmse(double rmse) const {
    return opt.max_rmse_growth <= 0 || recent_count < kRecentMin || rmse <= kRmseFloor ||
           rmse <= opt.max_rmse_growth * recent_median();
  }

  // The RMSE of the last kRecent placed frames (a ring) and its median.
  static constexpr size_t kRecent = 20, kRecentMin = 3;
  double recent[kRecent] = {};
  size_t recent_count = 0, recent_next = 0;
  void remember_rmse(double rmse) {
    recent[recent_next] = rmse;
    recent_next = (recent_next + 1) % kRecent;
    recent_count = std::min(recent_count + 1, kRecent);
  }
  double recent_median() const {
    double v[kRecent];
    std::copy(recent, recent + recent_count, v);
    std::nth_element(v, v + recent_count / 2, v + recent_count);
    return v[recent_count / 2];
  }

  // A registration from pose p (the tracked frame's, when it moved far): true with the registered
  // pose in *p when it converged, the keyframe rendered there and the frame aligned to it passes.
  // The basin test of a pose q that registration placed (the keyframe rendered at q): aligned again
  // from 4 starts turned basin_check_deg about the camera centre (pan and tilt), each must come back
  // within 1 degree of q. A look-alike pose near the true one is a shallow local minimum: from some
  // side the alignment slides away from it.
  bool stable(const Pose& q, int* iterations) {
    if (opt.basin_check_deg <= 0) return true;
    const double a = opt.basin_check_deg * kPi / 180.0;
    static const int kTurns[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    for (const auto& turn : kTurns) {
      Pose start = q;
      const double xi[6] = {0, 0, 0, turn[1] * a, turn[0] * a, 0};
      apply_left_twist(xi, &start);
      align(&start, iterations);
      if (rotation_error_deg(start, q) > 1.0) return false;
    }
    return true;
  }

  Status verify(const uint8_t* rgb, Pose* p, TrackResult* out, bool* ok) {
    *ok = false;
    RegisterResult rr;
    GS_RETURN_IF_ERROR(registrar->register_view(rgb, full, *p, &rr));
    out->iterations += rr.iterations;
    if (!rr.converged()) return Status::Ok();
    Pose q = rr.pose;
    GS_RETURN_IF_ERROR(render_keyframe(q));
    out->new_keyframe = true;
    const Sums s = align(&q, &out->iterations);
    fill_stats(s, out);
    if (!good(s, *out) || !stable(q, &out->iterations)) return Status::Ok();
    *p = q;
    *ok = true;
    return Status::Ok();
  }

  Pose predict(double time) const {
    if (!opt.motion_model || history < 2) return last[0];
    double xi[6];
    left_difference(last[1], last[0], xi);  // the last step
    const double dt_last = last_time[0] - last_time[1], dt = time - last_time[0];
    const double f = dt_last > 0 ? std::min(dt / dt_last, 3.0) : 1.0;
    for (double& v : xi) v *= f;
    Pose p = last[0];
    apply_left_twist(xi, &p);
    return p;
  }

  void remember(const Pose& p, double time) {
    last[1] = last[0];
    last_time[1] = last_time[0];
    last[0] = p;
    last_time[0] = time;
    history = std::min(history + 1, 2);
  }

  // Ranks the candidates and the keyframe ring by their descriptors against the frame's.
  void rank() {
    const FrameLevel& c = frame[size_t(levels - 1)];
    detail::grey_descriptor(c.rgb.data(), size_t(c.in.width) * size_t(c.in.height), frame_desc.data());
    ranked.clear();
    auto dist = [&](const float* d) { return detail::descriptor_distance(d, frame_desc.data(), desc_dim); };
    for (size_t i = 0; i < cand.size(); ++i) ranked.emplace_back(dist(cand_desc.data() + i * desc_dim), int(i));
    for (size_t i = 0; i < ring_count; ++i) ranked.emplace_back(dist(ring_desc.data() + i * desc_dim), -1 - int(i));
    std::sort(ranked.begin(), ranked.end());
  }

  // A pose found by one of the relocalisation's registrations: where it started, the frame's
  // figures there, and how many registrations from other starts reached the same place.
  struct Found {
    Pose start, pose;
    double rmse = 0, explained = 0, coverage = 0;
    int agree = 0;
  };
  std::vector<Found> found;  // capacity planned at create(): relocalize_candidates + 1
  // The accuracy the tracker is asked for: 1 degree and 1 % of the scene extent.
  bool same_place(const Pose& a, const Pose& b) const {
    return rotation_error_deg(a, b) <= 1.0 && centre_distance(a, b) <= 0.01 * extent;
  }

  // Registration from the best-ranked poses (and first from the last pose when the previous frame
  // was placed). A converged pose that fits the frame (the verdict's absolute bounds) is a
  // candidate; it is accepted when its RMSE is usual for the stream (max_rmse_growth) or when a
  // registration from another start (over 1 degree or 1 % away) reached the same place. A
  // look-alike is a local minimum one start slides into; a view the model renders worse than the
  // stream's usual (a held-out photo, a blurred one) is still where starts from several sides meet.
  // The accepted candidate with the lowest RMSE wins if it also passes the basin test, not the
  // first; the search stops early once a pose is both usual and agreed. (snowmiku_plush's photos
  // in capture order, first-wins and the growth bound alone: one frame whose three candidate starts
  // met at its true pose was lost, and two were placed 1.85 degrees and 1.2 % of the radius off by
  // the last pose's start while a candidate's start reached the true pose at a lower RMSE.)
  Status relocalize(const uint8_t* rgb, TrackResult* out, int* iterations, bool* placed_out) {
    *placed_out = false;
    rank();
    found.clear();
    const int tries = std::max(0, opt.relocalize_candidates);
    int tried = 0;
    for (int i = -1; i < int(ranked.size()) && tried < tries + (placed ? 1 : 0); ++i) {
      Pose from;
      if (i < 0) {
        if (!placed) continue;
        from = last[0];
      } else {
        const int id = ranked[size_t(i)].second;
        from = id >= 0 ? cand[size_t(id)] : ring[size_t(-1 - id)];
      }
      ++tried;
      RegisterResult rr;
      GS_RETURN_IF_ERROR(registrar->register_view(rgb, full, from, &rr));
      *iterations += rr.iterations;
      if (!rr.converged()) continue;
      Found f;
      f.start = from;
      f.pose = rr.pose;
      GS_RETURN_IF_ERROR(render_keyframe(f.pose));
      const Sums s = align(&f.pose, iterations);
      TrackResult r;
      fill_stats(s, &r);
      if (!fits(s, r)) continue;
      f.rmse = r.rmse, f.explained = r.explained, f.coverage = r.coverage;
      bool settled = false;
      for (Found& g : found)
        if (same_place(g.pose, f.pose) && !same_place(g.start, f.start)) {
          ++g.agree, ++f.agree;
          settled = settled || usual_rmse(f.rmse) || usual_rmse(g.rmse);
        }
      found.push_back(f);
      if (settled) break;
    }
    // Accepted candidates by RMSE, lowest first (at most relocalize_candidates + 1; sorting in place
    // allocates nothing).
    std::sort(found.begin(), found.end(), [](const Found& a, const Found& b) { return a.rmse < b.rmse; });
    for (const Found& f : found) {
      if (!usual_rmse(f.rmse) && f.agree == 0) continue;
      GS_RETURN_IF_ERROR(render_keyframe(f.pose));
      if (!stable(f.pose, iterations)) continue;
      out->pose = f.pose;
      out->rmse = f.rmse, out->explained = f.explained, out->coverage = f.coverage;
      out->new_keyframe = true;
      *placed_out = true;
      return Status::Ok();
    }
    if (!found.empty()) out->rmse = found[0].rmse, out->explained = found[0].explained, out->coverage = found[0].coverage;
    return Status::Ok();
  }
};

Tracker::Tracker() : impl_(new Impl) {}
Tracker::~Tracker() = default;

Expected<std::unique_ptr<Tracker>> Tracker::create(const model::HybridModel& model, const PinholeIntrinsics& frame,
                                                   const TrackOptions& options, platform::ThreadPool* pool,
                                                   const simd::KernelTable* kernels) {
  if (frame.width <= 0 || frame.height <= 0 || !(frame.fx > 0) || !(frame.fy > 0) || !std::isfinite(frame.cx) ||
      !std::isfinite(frame.cy))
    return invalid_argument("tracker: invalid frame intrinsics (size " + std::to_string(frame.width) + "x" +
                            std::to_string(frame.height) + ", positive focal lengths expected)");
  if (options.track_downscale < 1 || options.track_downscale > 16)
    return invalid_argument("tracker: track_downscale " + std::to_string(options.track_downscale) + " is not in 1..16");
  if (options.levels < 1 || options.levels > 6)
    return invalid_argument("tracker: levels " + std::to_string(options.levels) + " is not in 1..6");
  if (!(options.huber_delta > 0) || !std::isfinite(options.huber_delta))
    return invalid_argument("tracker: huber_delta must be positive");
  if (!std::isfinite(options.chroma_weight)) return invalid_argument("tracker: chroma_weight must be finite");
  if (options.iterations_per_level < 1)
    return invalid_argument("tracker: iterations_per_level must be at least 1");
  const int coarsest = options.track_downscale << (options.levels - 1);
  if (frame.width / coarsest < 8 || frame.height / coarsest < 6)
    return invalid_argument("tracker: a " + std::to_string(frame.width) + "x" + std::to_string(frame.height) +
                            " frame is too small for " + std::to_string(options.levels) + " levels below 1/" +
                            std::to_string(options.track_downscale) + " (the coarsest must be at least 8x6)");
  std::unique_ptr<Tracker> t(new Tracker());
  Impl& d = *t->impl_;
  d.opt = options;
  d.pool = pool;
  d.full = frame;
  d.levels = options.levels;
  d.extent = model.scene_extent > 0 ? model.scene_extent : 1.0;
  RegisterOptions reg = options.relocalize;
  reg.fixed_point = options.fixed_point;
  for (int c = 0; c < 3; ++c) reg.background[c] = options.background[c];
  Expected<std::unique_ptr<Registrar>> r = Registrar::create(model, frame.width, frame.height, reg, pool, kernels);
  if (!r.ok()) return r.status();
  d.registrar = std::move(r).value();
  const size_t px = size_t(frame.width) * size_t(frame.height);
  d.key_rgb.assign(3 * px, 0.0f);
  d.key_alpha.assign(px, 0.0f);
  d.key_depth.assign(px, 0.0f);
  const Camera level0 = scaled_camera(Camera{frame, Pose{}}, options.track_downscale);
  const size_t px0 = size_t(level0.intr.width) * size_t(level0.intr.height);
  d.lvl_rgb.assign(3 * px0, 0.0f);
  d.lvl_alpha.assign(px0, 0.0f);
  d.lvl_depth.assign(px0, 0.0f);
  d.key.resize(size_t(d.levels));
  d.frame.resize(size_t(d.levels));
  uint64_t bytes = (5 * px + 5 * px0) * sizeof(float);
  for (int l = 0; l < d.levels; ++l) {
    const PinholeIntrinsics in = scaled_camera(Camera{frame, Pose{}}, d.factor(l)).intr;
    const size_t n = size_t(in.width) * size_t(in.height);
    d.key[size_t(l)].in = d.frame[size_t(l)].in = in;
    d.key[size_t(l)].xyz.assign(3 * n, 0.0f);
    d.key[size_t(l)].rgb.assign(3 * n, 0.0f);
    d.frame[size_t(l)].rgb.assign(3 * n, 0.0f);
    bytes += 9 * n * sizeof(float);
  }
  d.partial.resize((px0 + kChunk - 1) / kChunk);
  const PinholeIntrinsics& coarse = d.frame[size_t(d.levels - 1)].in;
  d.desc_dim = size_t(coarse.width) * size_t(coarse.height);
  d.ring_desc.assign(kKeyframeRing * d.desc_dim, 0.0f);
  d.frame_desc.assign(d.desc_dim, 0.0f);
  d.key_desc.assign(d.desc_dim, 0.0f);
  d.ranked.reserve(kKeyframeRing);
  d.found.reserve(size_t(std::max(0, options.relocalize_candidates)) + 1);
  d.bytes = bytes + d.partial.size() * sizeof(Sums) + (kKeyframeRing + 1) * d.desc_dim * sizeof(float) +
            d.registrar->planned_bytes();
  return t;
}

Status Tracker::set_candidates(const std::vector<Pose>& poses) {
  Impl& d = *impl_;
  d.cand = poses;
  d.cand_desc.assign(poses.size() * d.desc_dim, 0.0f);
  d.ranked.reserve(poses.size() + kKeyframeRing);
  const int f = d.factor(d.levels - 1);
  for (size_t i = 0; i < poses.size(); ++i) {
    GS_RETURN_IF_ERROR(d.registrar->render(d.camera(poses[i]), d.key_rgb.data()));
    io::box_downsample_float(d.key_rgb.data(), d.full.width, d.full.height, 3, f, d.lvl_rgb.data());
    detail::grey_descriptor(d.lvl_rgb.data(), d.desc_dim, d.cand_desc.data() + i * d.desc_dim);
  }
  d.have_key = false;  // the keyframe buffers held the candidates' renders
  return poses.empty() ? Status::Ok() : d.warm_registrar(poses[0]);
}

Status Tracker::reset(const Pose& start) {
  GS_RETURN_IF_ERROR(impl_->warm_registrar(start));
  impl_->start = start;
  impl_->have_start = true;
  impl_->placed = false;
  impl_->history = 0;
  return Status::Ok();
}

void Tracker::reset() {
  impl_->have_start = false;
  impl_->placed = false;
  impl_->history = 0;
}

Status Tracker::track(const uint8_t* rgb, double time, TrackResult* out) {
  Impl& d = *impl_;
  if (!rgb || !out) return invalid_argument("tracker: null frame or result");
  if (!std::isfinite(time) || time < d.previous_time)
    return invalid_argument("tracker: frame time " + std::to_string(time) + " s is not after the previous frame's " +
                            std::to_string(d.previous_time) + " s");
  d.previous_time = time;
  const uint64_t t0 = platform::now_ns();
  *out = TrackResult{};
  d.prepare(rgb);
  const uint64_t t1 = platform::now_ns();
  uint64_t t_align = 0, t_key = 0, t_reloc = 0;
  bool placed = false;
  if (d.placed || d.have_start) {
    Pose p = d.placed ? d.predict(time) : d.start;
    d.have_start = false;
    if (!d.have_key || !d.placed) {  // a start pose, or the keyframe is gone: render at the start
      const uint64_t k0 = platform::now_ns();
      GS_RETURN_IF_ERROR(d.render_keyframe(p));
      out->new_keyframe = true;
      t_key += platform::now_ns() - k0;
    }
    const uint64_t a0 = platform::now_ns();
    const Pose predicted = p;
    Sums s = d.align(&p, &out->iterations);
    d.fill_stats(s, out);
    t_align += platform::now_ns() - a0;
    // A frame-to-frame move far beyond a hand's is a look-alike pose, not the camera's: relocalise.
    const bool plausible = rotation_error_deg(p, predicted) <= d.opt.max_correction_deg &&
                           centre_distance(p, predicted) <= d.opt.max_correction_translation * d.extent;
    placed = plausible && d.good(s, *out);
    if (placed && d.opt.verify_correction_deg > 0 && rotation_error_deg(p, predicted) > d.opt.verify_correction_deg) {
      const uint64_t r0 = platform::now_ns();
      GS_RETURN_IF_ERROR(d.verify(rgb, &p, out, &placed));
      t_reloc += platform::now_ns() - r0;
    }
    if (placed) {
      if (d.key_rmse < 0) d.key_rmse = out->rmse;
      const bool far = rotation_error_deg(p, d.key_pose) > d.opt.keyframe_rotation_deg ||
                       centre_distance(p, d.key_pose) > d.opt.keyframe_translation * d.extent ||
                       out->rmse > d.opt.keyframe_rmse_growth * d.key_rmse;
      if (far) {  // a new keyframe at the pose found, and the frame aligned to it once more
        const uint64_t k0 = platform::now_ns();
        GS_RETURN_IF_ERROR(d.render_keyframe(p));
        out->new_keyframe = true;
        t_key += platform::now_ns() - k0;
        const uint64_t a1 = platform::now_ns();
        Pose q = p;
        s = d.align(&q, &out->iterations);
        TrackResult again = *out;
        d.fill_stats(s, &again);
        if (d.good(s, again)) p = q, *out = again;
        t_align += platform::now_ns() - a1;
      }
      out->pose = p;
      out->verdict = TrackVerdict::kTracking;
    }
  }
  if (!placed) {
    const uint64_t r0 = platform::now_ns();
    bool found = false;
    GS_RETURN_IF_ERROR(d.relocalize(rgb, out, &out->iterations, &found));
    t_reloc += platform::now_ns() - r0;
    if (found) {
      out->verdict = TrackVerdict::kRelocalized;
      placed = true;
      d.history = 0;  // no velocity across a jump
    } else {
      out->verdict = TrackVerdict::kLost;
      d.history = 0;
    }
  }
  if (placed) d.remember(out->pose, time), d.remember_rmse(out->rmse);
  if (placed && out->new_keyframe) d.keep_keyframe();
  d.placed = placed;
  out->keyframes = d.keyframes;
  const uint64_t t_end = platform::now_ns();
  out->ms.prepare = double(t1 - t0) * 1e-6;
  out->ms.align = double(t_align) * 1e-6;
  out->ms.keyframe = double(t_key) * 1e-6;
  out->ms.relocalize = double(t_reloc) * 1e-6;
  out->ms.total = double(t_end - t0) * 1e-6;
  return Status::Ok();
}

const TrackOptions& Tracker::options() const { return impl_->opt; }
uint64_t Tracker::planned_bytes() const { return impl_->bytes; }

}  // namespace gs::pose
