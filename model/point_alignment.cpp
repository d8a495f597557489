// SPDX-License-Identifier: MIT
// Photometric alignment of camera poses to fixed SfM points (see gs/model/point_alignment.h).
#include "gs/model/point_alignment.h"

#include <algorithm>
#include <cmath>

#include "pose_solve.h"
#include "gs/platform/clock.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "gs/stats.h"

namespace gs::pose {

namespace {

using detail::huber_cost;
using detail::huber_weight;

struct LevelImage {
  int w = 0, h = 0;
  std::vector<float> rgb;  // [h, w, 3] in [0, 1]
};

bool sample(const LevelImage& im, double u, double v, double c[3], double cu[3], double cv[3]) {
  return detail::sample_bilinear(detail::RgbView{im.rgb.data(), im.w, im.h}, u, v, c, cu, cv);
}

// Camera-space point and projection of world point X under (R, t) (double).
struct Projected {
  double m[3], u, v;
};
inline Projected project(const double R[9], const double t[3], const PinholeIntrinsics& in, const float* X) {
  Projected p;
  for (int r = 0; r < 3; ++r) p.m[r] = R[3 * r] * X[0] + R[3 * r + 1] * X[1] + R[3 * r + 2] * X[2] + t[r];
  p.u = in.fx * p.m[0] / p.m[2] + in.cx;
  p.v = in.fy * p.m[1] / p.m[2] + in.cy;
  return p;
}

void pose_to_double(const Pose& pose, double R[9], double t[3]) {
  for (int i = 0; i < 9; ++i) R[i] = pose.R[i];
  for (int i = 0; i < 3; ++i) t[i] = pose.t[i];
}

constexpr double kNear = 0.05;  // camera-space depth below which a point is ignored

// An even subsample of at most max_points points, colours in [0, 1] (empty without rgb).
struct PointSample {
  std::vector<float> xyz, rgb;
};
PointSample subsample_points(const float* xyz, const uint8_t* rgb, size_t n, size_t max_points) {
  PointSample out;
  const size_t stride = std::max<size_t>((n + max_points - 1) / std::max<size_t>(max_points, 1), 1);
  for (size_t p = 0; p < n; p += stride) {
    out.xyz.insert(out.xyz.end(), xyz + 3 * p, xyz + 3 * p + 3);
    if (rgb)
      for (int k = 0; k < 3; ++k) out.rgb.push_back(float(rgb[3 * p + size_t(k)]) / 255.0f);
  }
  return out;
}

struct Aligner {
  const float* xyz = nullptr;
  const float* known = nullptr;                   // [n, 3] fixed point colours, or null
  size_t n = 0;                                   // points used
  std::vector<LevelImage> images;                 // [views] at the current level
  std::vector<PinholeIntrinsics> intr;            // [views] at the current level
  std::vector<Camera>* cameras = nullptr;
  const PointAlignOptions* opt = nullptr;
  double radius = 1;                              // scene radius (camera centres), for the trust region
  std::vector<uint8_t> visible;                   // [views, n]
  std::vector<float> colour;                      // [views, n, 3] sample at the round's start
  std::vector<double> sum;                        // [n, 3] over visible views
  std::vector<int32_t> count;                     // [n]
  std::vector<std::vector<float>> zbuf;           // per view [h, w]

  size_t views() const { return cameras->size(); }

  void setup(const PointSample& points, std::vector<Camera>* cams, const PointAlignOptions* options) {
    xyz = points.xyz.data();
    known = points.rgb.empty() ? nullptr : points.rgb.data();
    n = points.xyz.size() / 3;
    cameras = cams;
    opt = options;
    std::vector<Pose> poses;
    for (const Camera& c : *cameras) poses.push_back(c.pose);
    double centre[3];
    pose::scene_frame(poses.data(), poses.size(), centre, &radius);
    const size_t V = cameras->size();
    images.resize(V);
    intr.resize(V);
    zbuf.resize(V);
    visible.assign(V * n, 0);
    colour.assign(V * n * 3, 0.0f);
    sum.assign(n * 3, 0.0);
    count.assign(n, 0);
  }

  // View v's image at level s (a box-filtered 1/s of it), its intrinsics there, and a fresh z-buffer.
  void load_level(size_t v, const io::Image8& im, int s) {
    LevelImage& L = images[v];
    L.w = im.width / s;
    L.h = im.height / s;
    L.rgb.resize(size_t(L.w) * size_t(L.h) * 3);
    io::box_downsample_rgb(im.pixels.data(), im.width, im.height, s, L.rgb.data());
    intr[v] = scaled_camera((*cameras)[v], s).intr;
    zbuf[v].assign(size_t(im.width) * size_t(im.height), INFINITY);
  }

  // Visibility (in front, inside, not behind the z-buffer) and colour of every point in view v.
  // The z-buffer lives at full resolution (a coarse one would let every near point hide the far
  // points around it), the colours come from the current level.
  void observe(size_t v) {
    double R[9], t[3];
    pose_to_double((*cameras)[v].pose, R, t);
    const PinholeIntrinsics& fin = (*cameras)[v].intr;
    const LevelImage& im = images[v];
    std::vector<float>& zb = zbuf[v];
    std::fill(zb.begin(), zb.end(), INFINITY);
    for (size_t p = 0; p < n; ++p) {
      const Projected q = project(R, t, fin, xyz + 3 * p);
      if (!(q.m[2] > kNear) || !(q.u >= 0 && q.v >= 0 && q.u < fin.width && q.v < fin.height)) continue;
      float& z = zb[size_t(int(q.v)) * size_t(fin.width) + size_t(int(q.u))];
      z = std::min(z, float(q.m[2]));
    }
    uint8_t* vis = &visible[v * n];
    float* col = &colour[v * n * 3];
    for (size_t p = 0; p < n; ++p) {
      vis[p] = 0;
      const Projected f = project(R, t, fin, xyz + 3 * p);
      if (!(f.m[2] > kNear) || !(f.u >= 0 && f.v >= 0 && f.u < fin.width && f.v < fin.height)) continue;
      // Occluded if a nearer point sits in the 3 x 3 pixel neighbourhood (sparse clouds leave holes).
      const int x = int(f.u), y = int(f.v);
      float zmin = INFINITY;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx >= 0 && yy >= 0 && xx < fin.width && yy < fin.height) zmin = std::min(zmin, zb[size_t(yy) * size_t(fin.width) + size_t(xx)]);
        }
      if (f.m[2] > double(zmin) * (1.0 + opt->occlusion_tolerance)) continue;
      const Projected q = project(R, t, intr[v], xyz + 3 * p);
      double c[3], cu[3], cv[3];
      if (!sample(im, q.u, q.v, c, cu, cv)) continue;
      vis[p] = 1;
      for (int k = 0; k < 3; ++k) col[3 * p + size_t(k)] = float(c[k]);
    }
  }

  void accumulate_means() {
    std::fill(sum.begin(), sum.end(), 0.0);
    std::fill(count.begin(), count.end(), 0);
    for (size_t v = 0; v < views(); ++v)
      for (size_t p = 0; p < n; ++p)
        if (visible[v * n + p]) {
          for (int k = 0; k < 3; ++k) sum[3 * p + size_t(k)] += colour[(v * n + p) * 3 + size_t(k)];
          ++count[p];
        }
  }

  // Leave-one-out mean colour of point p seen from views other than v (v sees it).
  void target(size_t v, size_t p, double out[3]) const {
    if (known) {
      for (int k = 0; k < 3; ++k) out[k] = known[3 * p + size_t(k)];
      return;
    }
    const double inv = 1.0 / double(count[p] - 1);
    for (int k = 0; k < 3; ++k) out[k] = (sum[3 * p + size_t(k)] - colour[(v * n + p) * 3 + size_t(k)]) * inv;
  }

  // Mean Huber cost of view v at pose (R, t) over the points it saw at the round's start (a point
  // that leaves the image counts as a full-delta residual, so leaving is not a way to lower it);
  // optionally the normal equations.
  double cost(size_t v, const double R[9], const double t[3], detail::Mat6* A,
              detail::Vec6* b) const {
    const double delta = opt->huber;
    double total = 0;
    size_t used = 0;
    if (A) A->setZero(), b->setZero();
    for (size_t p = 0; p < n; ++p) {
      if (!visible[v * n + p] || (!known && count[p] < 2)) continue;
      ++used;
      const Projected q = project(R, t, intr[v], xyz + 3 * p);
      double c[3], cu[3], cv[3];
      if (!(q.m[2] > kNear) || !sample(images[v], q.u, q.v, c, cu, cv)) {
        total += huber_cost(2 * delta, delta);
        continue;
      }
      double tg[3], r[3];
      target(v, p, tg);
      for (int k = 0; k < 3; ++k) r[k] = c[k] - tg[k];
      const double rn = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
      total += huber_cost(rn, delta);
      if (!A) continue;
      double du[6], dv[6];
      detail::projection_twist_jacobian(q.m, intr[v].fx, intr[v].fy, du, dv);
      const double w = huber_weight(rn, delta);
      for (int k = 0; k < 3; ++k) {
        double J[6];
        for (int j = 0; j < 6; ++j) J[j] = cu[k] * du[j] + cv[k] * dv[j];
        for (int i = 0; i < 6; ++i) {
          (*b)(i) += w * J[i] * r[k];
          for (int j = 0; j < 6; ++j) (*A)(i, j) += w * J[i] * J[j];
        }
      }
    }
    return used ? total / double(used) : 0.0;
  }

  // Levenberg-Marquardt on view v's pose with the round's targets fixed; returns the final cost.
  double refine_view(size_t v) {
    Pose& pose = (*cameras)[v].pose;
    double R[9], t[3];
    pose_to_double(pose, R, t);
    detail::Mat6 A;
    detail::Vec6 b;
    double c = cost(v, R, t, &A, &b);
    double lambda = 1e-2;
    for (int it = 0; it < opt->gn_iterations; ++it) {
      bool accepted = false;
      for (int attempt = 0; attempt < 6 && !accepted; ++attempt) {
        // Trust region: at most 1 degree and 1 % of the scene radius per step.
        double xi[6];
        detail::damped_step(A, b, lambda, 0.01745, 0.01 * radius, xi);
        Pose trial = pose;
        pose::apply_left_twist(xi, &trial);
        double Rt[9], tt[3];
        pose_to_double(trial, Rt, tt);
        const double ct = cost(v, Rt, tt, nullptr, nullptr);
        if (ct < c) {
          pose = trial;
          std::copy(Rt, Rt + 9, R);
          std::copy(tt, tt + 3, t);
          c = cost(v, R, t, &A, &b);
          lambda = std::max(lambda / 3, 1e-6);
          accepted = true;
        } else {
          lambda *= 5;
        }
      }
      if (!accepted) break;
    }
    return c;
  }
};

// How far each view moved from its start; views whose move is not to be trusted (see
// PointAlignOptions) get their start pose back.
void keep_trusted_moves(const std::vector<Pose>& start, double radius, const PointAlignOptions& options,
                        std::vector<Camera>* cameras, PointAlignReport* rep) {
  const size_t V = start.size();
  std::vector<double> move_deg(V), move_frac(V);
  for (size_t v = 0; v < V; ++v) {
    double a[3], b[3];
    pose::centre(start[v], a);
    pose::centre((*cameras)[v].pose, b);
    move_deg[v] = pose::rotation_error_deg(start[v], (*cameras)[v].pose);
    move_frac[v] = std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2])) / radius;
  }
  rep->median_move_deg = median(move_deg);
  rep->median_move_frac = median(move_frac);
  rep->discarded = rep->median_move_deg < options.discard_below_median_move_deg;
  const double k = options.max_move_over_median;
  for (size_t v = 0; v < V; ++v) {
    const bool too_far = k > 0 && (move_deg[v] > k * rep->median_move_deg || move_frac[v] > k * rep->median_move_frac);
    if (!rep->discarded && !too_far) continue;
    (*cameras)[v].pose = start[v];
    rep->reverted_views.push_back(int(v));
  }
}

}  // namespace

Status align_poses_to_points(const float* xyz, const uint8_t* rgb, size_t n, const std::vector<const io::Image8*>& images,
                             std::vector<Camera>* cameras, const PointAlignOptions& options, platform::ThreadPool* pool,
                             PointAlignReport* report) {
  const double t0 = platform::now_seconds();
  if (!cameras || images.size() != cameras->size()) return invalid_argument("point alignment: one image per camera needed");
  if (cameras->size() < 2) return invalid_argument("point alignment: needs at least 2 views");
  if (n < 10) return invalid_argument("point alignment: needs at least 10 SfM points");
  for (size_t v = 0; v < images.size(); ++v) {
    const io::Image8& im = *images[v];
    const PinholeIntrinsics& in = (*cameras)[v].intr;
    if (im.channels != 3 || im.width != in.width || im.height != in.height)
      return invalid_argument("point alignment: image " + std::to_string(v) + " does not match its camera");
  }
  const PointSample points = subsample_points(xyz, rgb, n, options.max_points);
  Aligner al;
  al.setup(points, cameras, &options);
  const size_t V = cameras->size();
  std::vector<Pose> start;
  for (const Camera& c : *cameras) start.push_back(c.pose);

  // Coarsest level: halvings while every image stays min_width wide.
  int min_w = (*cameras)[0].intr.width;
  for (const Camera& c : *cameras) min_w = std::min(min_w, c.intr.width);
  int coarsest = 1, levels = 1;
  while (levels < options.max_levels && min_w / (coarsest * 2) >= options.min_width) coarsest *= 2, ++levels;

  auto for_views = [&](auto&& fn) {
    auto body = [&](size_t b, size_t e, int) {
      for (size_t v = b; v < e; ++v) fn(v);
    };
    if (pool) pool->parallel_for(V, 1, body);
    else body(0, V, 0);
  };
  PointAlignReport rep;
  rep.points_used = al.n;
  for (int s = coarsest; s >= 1; s /= 2) {
    for_views([&](size_t v) { al.load_level(v, *images[v], s); });
    for (int round = 0; round < options.rounds_per_level; ++round) {
      for_views([&](size_t v) { al.observe(v); });
      al.accumulate_means();
      std::vector<double> costs(V, 0.0);
      if (s == 1 && round == 0) {
        double total = 0;
        for (size_t v = 0; v < V; ++v) {
          double R[9], t[3];
          pose_to_double((*cameras)[v].pose, R, t);
          total += al.cost(v, R, t, nullptr, nullptr);
        }
        rep.initial_cost = total / double(V);
      }
      for_views([&](size_t v) { costs[v] = al.refine_view(v); });
      double total = 0;
      for (double c : costs) total += c;
      rep.final_cost = total / double(V);
      ++rep.rounds;
    }
    ++rep.levels;
  }
  keep_trusted_moves(start, al.radius, options, cameras, &rep);
  rep.seconds = platform::now_seconds() - t0;
  if (report) *report = rep;
  return Status::Ok();
}

Status score_views_against_points(const float* xyz, const uint8_t* rgb, size_t n, const std::vector<const io::Image8*>& images,
                                  const std::vector<Camera>& cameras, double huber, size_t max_points,
                                  platform::ThreadPool* pool, std::vector<ViewPointAgreement>* scores) {
  if (images.size() != cameras.size()) return invalid_argument("point agreement: one image per camera needed");
  for (size_t v = 0; v < images.size(); ++v) {
    const io::Image8& im = *images[v];
    if (im.channels != 3 || im.width != cameras[v].intr.width || im.height != cameras[v].intr.height)
      return invalid_argument("point agreement: image " + std::to_string(v) + " does not match its camera");
  }
  scores->assign(cameras.size(), ViewPointAgreement{});
  if (cameras.empty() || n == 0) return Status::Ok();
  // With the points' own colours every view is scored on its own, one at a time: a full-resolution
  // z-buffer and the samples of every view at once were 60 MiB on snowmiku_plush (84 views), the
  // peak of a whole training run. Leave-one-out means need every view's samples together.
  if (rgb && cameras.size() > 1) {
    for (size_t v = 0; v < cameras.size(); ++v) {
      std::vector<ViewPointAgreement> one;
      GS_RETURN_IF_ERROR(score_views_against_points(xyz, rgb, n, {images[v]}, {cameras[v]}, huber, max_points, pool, &one));
      (*scores)[v] = one[0];
    }
    return Status::Ok();
  }
  PointAlignOptions options;
  options.huber = huber;
  options.max_points = max_points;
  const PointSample points = subsample_points(xyz, rgb, n, max_points);
  std::vector<Camera> cams = cameras;
  Aligner al;
  al.setup(points, &cams, &options);
  const size_t V = cams.size();
  auto for_views = [&](auto&& fn) {
    auto body = [&](size_t b, size_t e, int) {
      for (size_t v = b; v < e; ++v) fn(v);
    };
    if (pool) pool->parallel_for(V, 1, body);
    else body(0, V, 0);
  };
  for_views([&](size_t v) {
    al.load_level(v, *images[v], 1);
    al.observe(v);
  });
  al.accumulate_means();
  const double h2 = huber * huber;
  for_views([&](size_t v) {
    std::vector<size_t> seen;
    for (size_t p = 0; p < al.n; ++p)
      if (al.visible[v * al.n + p] && (al.known || al.count[p] >= 2)) seen.push_back(p);
    ViewPointAgreement& out = (*scores)[v];
    out.visible = seen.size();
    if (seen.empty()) return;
    // The chance pairing: each point against the sample of the point a third of the list further
    // on (far apart in the image for any ordering of the cloud that is not spatial).
    const size_t shift = std::max<size_t>(1, seen.size() / 3);
    size_t agree = 0, chance = 0;
    for (size_t i = 0; i < seen.size(); ++i) {
      const size_t p = seen[i], q = seen[(i + shift) % seen.size()];
      double tg[3];
      al.target(v, p, tg);
      double d2 = 0, c2 = 0;
      for (int k = 0; k < 3; ++k) {
        const double a = al.colour[(v * al.n + p) * 3 + size_t(k)] - tg[k];
        const double b = al.colour[(v * al.n + q) * 3 + size_t(k)] - tg[k];
        d2 += a * a, c2 += b * b;
      }
      agree += d2 <= h2;
      chance += c2 <= h2;
    }
    out.agree = double(agree) / double(seen.size());
    out.chance = double(chance) / double(seen.size());
  });
  return Status::Ok();
}

TypicalAgreement typical_agreement(const std::vector<ViewPointAgreement>& scores) {
  std::vector<double> agree, chance, visible;
  for (const ViewPointAgreement& s : scores) agree.push_back(s.agree), chance.push_back(s.chance), visible.push_back(double(s.visible));
  TypicalAgreement t;
  if (scores.empty()) return t;
  t.margin = median(agree) - median(chance);
  t.points = median(visible);
  return t;
}

bool is_suspect(const ViewPointAgreement& score, const TypicalAgreement& typical) {
  return score.agree - score.chance < 0.25 * typical.margin || double(score.visible) < 0.25 * typical.points;
}

bool prefers(const ViewPointAgreement& moved, const ViewPointAgreement& given, const TypicalAgreement& typical) {
  return !is_suspect(moved, typical) && (moved.agree - moved.chance) - (given.agree - given.chance) >= 0.25 * typical.margin;
}

std::vector<uint8_t> suspect_views(const std::vector<ViewPointAgreement>& scores) {
  std::vector<uint8_t> flags(scores.size(), 0);
  if (scores.size() < 3) return flags;
  const TypicalAgreement typical = typical_agreement(scores);
  if (!(typical.margin >= 0.1)) return flags;
  for (size_t v = 0; v < scores.size(); ++v) flags[v] = is_suspect(scores[v], typical);
  return flags;
}

}  // namespace gs::pose
