// SPDX-License-Identifier: MIT
// generate_scene: places the cameras, renders every view, samples the sparse points with their
// visibility tracks and writes the result as a COLMAP text model plus PNG images.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "dataset_parts.h"
#include "gs/constants.h"
#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "gs/platform/thread_pool.h"
#include "hbgs/synth.h"
#include "procedural.h"
#include "view_math.h"

namespace hbgs::synth {

namespace detail {

double focal_for(int width) { return std::round(0.9 * width * 4.0) / 4.0; }

gs::PinholeIntrinsics synth_intrinsics(int width, int height) {
  gs::PinholeIntrinsics intr;
  intr.width = width;
  intr.height = height;
  intr.fx = intr.fy = float(focal_for(width));
  intr.cx = float(width / 2.0);
  intr.cy = float(height / 2.0);
  return intr;
}

gs::Pose look_at(const double eye[3], const double at[3]) {
  double f[3] = {at[0] - eye[0], at[1] - eye[1], at[2] - eye[2]};
  double fn = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
  for (double& v : f) v /= fn;
  // right = f x up, up = +z; down = f x right keeps (right, down, forward) right-handed.
  double r[3] = {f[1], -f[0], 0.0};
  double rn = std::sqrt(r[0] * r[0] + r[1] * r[1]);
  for (double& v : r) v /= rn;
  double d[3] = {f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2], f[0] * r[1] - f[1] * r[0]};
  const double* rows[3] = {r, d, f};
  gs::Pose pose;
  for (int i = 0; i < 3; ++i) {
    double ti = 0;
    for (int j = 0; j < 3; ++j) {
      pose.R[3 * i + j] = float(rows[i][j]);
      ti -= rows[i][j] * eye[j];
    }
    pose.t[i] = float(ti);
  }
  return pose;
}

ViewSetup make_view(const gs::PinholeIntrinsics& intr, const double eye[3], const double at[3]) {
  return make_view(intr, look_at(eye, at));
}

ViewSetup make_view(const gs::PinholeIntrinsics& intr, const gs::Pose& pose) {
  ViewSetup v;
  gs::io::pose_to_colmap(pose, v.qvec, v.tvec);
  v.camera.intr = intr;
  v.camera.pose = gs::io::pose_from_colmap(v.qvec, v.tvec);
  return v;
}

std::vector<SparsePoint> sample_sparse_points(const Scene& scene, const std::vector<ViewSetup>& views,
                                              const std::vector<gs::io::Image8>& images, int num_points, float noise,
                                              uint64_t seed, int threads, const std::function<bool(const SceneHit&)>& accept,
                                              long long* draws_out, double fisheye_focal) {
  const int num_views = int(views.size());
  const gs::PinholeIntrinsics& K = views.front().camera.intr;
  const int W = K.width, H = K.height;
  constexpr double kHalfPi = 1.57079632679489661923;
  std::vector<ViewRays> rays;
  rays.reserve(size_t(num_views));
  for (const ViewSetup& v : views) {
    if (fisheye_focal > 0) rays.emplace_back(v.camera, fisheye_focal, kHalfPi);
    else rays.emplace_back(v.camera);
  }
  const double fx = K.fx, fy = K.fy, cx = K.cx, cy = K.cy;

  Rng prng(hash_combine(seed, 0x90175ULL));
  std::vector<SparsePoint> accepted;
  accepted.reserve(size_t(num_points));
  const int batch = 1024;
  const long long max_draws = 200LL * num_points + 10000;
  long long draws = 0;
  std::vector<SparsePoint> cands;
  std::vector<double> surface;  // [batch, 3] noise-free hit points used for the visibility test
  while (int(accepted.size()) < num_points && draws < max_draws) {
    cands.clear();
    surface.clear();
    while (int(cands.size()) < batch && draws < max_draws) {
      ++draws;
      int v = prng.below(num_views);
      int x = prng.below(W), y = prng.below(H);
      double o[3], d[3];
      if (!rays[size_t(v)].ray(x + 0.5, y + 0.5, o, d)) continue;  // outside the fisheye's circle
      SceneHit hit;
      if (!scene.intersect(o, d, &hit)) continue;
      if (!accept(hit)) continue;
      SparsePoint c;
      for (int k = 0; k < 3; ++k) c.xyz[k] = hit.position[k] + double(noise) * prng.normal();
      const gs::io::Image8& img = images[size_t(v)];
      const uint8_t* px = &img.pixels[(size_t(y) * size_t(W) + size_t(x)) * size_t(img.channels)];
      std::copy(px, px + 3, c.rgb);
      cands.push_back(std::move(c));
      surface.insert(surface.end(), hit.position, hit.position + 3);
    }
    gs::platform::ThreadPool pool(threads);
    pool.for_each_index(cands.size(), [&](size_t i) {
      SparsePoint& c = cands[i];
      const double* s = &surface[3 * i];
      for (int v = 0; v < num_views; ++v) {
        Projection p = fisheye_focal > 0 ? project_fisheye(views[size_t(v)].camera.pose, fisheye_focal, kHalfPi, cx, cy, c.xyz)
                                         : project(views[size_t(v)].camera.pose, fx, fy, cx, cy, c.xyz);
        if (!(p.cam[2] > 1e-6) || !(p.u >= 0 && p.u < W && p.v >= 0 && p.v < H)) continue;
        // Visibility of the noise-free surface point: nothing may lie between the camera centre
        // and it, up to a tolerance (1 mm + 1e-4 of the distance) that absorbs float round-off
        // of the hit itself.
        const double* ctr = rays[size_t(v)].centre();
        double dir[3] = {s[0] - ctr[0], s[1] - ctr[1], s[2] - ctr[2]};
        double dist = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        for (double& e : dir) e /= dist;
        if (scene.occluded(ctr, dir, dist - (1e-3 + 1e-4 * dist))) continue;
        c.track.push_back({uint32_t(v), p.u, p.v});
      }
    });
    // COLMAP only keeps points triangulated from at least two views (one if there is one view).
    const size_t min_track = num_views > 1 ? 2 : 1;
    for (SparsePoint& c : cands) {
      if (int(accepted.size()) >= num_points) break;
      if (c.track.size() >= min_track) accepted.push_back(std::move(c));
    }
  }
  if (draws_out) *draws_out = draws;
  return accepted;
}

gs::io::ColmapCamera colmap_pinhole(const gs::PinholeIntrinsics& K) {
  gs::io::ColmapCamera cam;
  cam.id = 1;
  cam.model = "PINHOLE";
  cam.width = K.width;
  cam.height = K.height;
  cam.params = {K.fx, K.fy, K.cx, K.cy};
  return cam;
}

gs::io::ColmapCamera colmap_fisheye(const gs::PinholeIntrinsics& K, double focal) {
  gs::io::ColmapCamera cam;
  cam.id = 1;
  cam.model = "OPENCV_FISHEYE";
  cam.width = K.width;
  cam.height = K.height;
  cam.params = {focal, focal, K.cx, K.cy, 0, 0, 0, 0};
  return cam;
}

gs::io::ColmapModel make_colmap_model(const std::vector<ViewSetup>& views, const std::vector<std::string>& names,
                                      const std::vector<SparsePoint>& points) {
  gs::io::ColmapModel model;
  model.cameras.push_back(colmap_pinhole(views.front().camera.intr));
  model.images.resize(views.size());
  for (size_t v = 0; v < views.size(); ++v) {
    gs::io::ColmapImage& im = model.images[v];
    im.id = uint32_t(v + 1);
    std::copy(views[v].qvec, views[v].qvec + 4, im.qvec);
    std::copy(views[v].tvec, views[v].tvec + 3, im.tvec);
    im.camera_id = 1;
    im.name = names[v];
  }
  model.points.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const SparsePoint& c = points[i];
    gs::io::ColmapPoint3D& pt = model.points[i];
    pt.id = uint64_t(i + 1);
    std::copy(c.xyz, c.xyz + 3, pt.xyz);
    std::copy(c.rgb, c.rgb + 3, pt.rgb);
    pt.error = 0.0;  // observations are exact projections
    for (const Observation& ob : c.track) {
      gs::io::ColmapImage& im = model.images[ob.view];
      gs::io::ColmapPoint2D p2;
      p2.xy[0] = ob.u;
      p2.xy[1] = ob.v;
      p2.point3d_id = int64_t(pt.id);
      pt.track.push_back({im.id, uint32_t(im.points2d.size())});
      im.points2d.push_back(p2);
    }
  }
  return model;
}

std::string view_name(int index, int digits, const std::string& extension) {
  std::string s = std::to_string(index);
  if (int(s.size()) < digits) s.insert(0, size_t(digits - int(s.size())), '0');
  return s + extension;
}

}  // namespace detail

namespace {

using detail::synth_intrinsics;
using detail::ViewSetup;

using gs::kPi;
constexpr const double (&kTarget)[3] = detail::kSceneTarget;

std::vector<ViewSetup> make_views(const SynthOptions& opt) {
  detail::Rng rng(detail::hash_combine(opt.seed, 0xca3e7a5ULL));
  const gs::PinholeIntrinsics intr = synth_intrinsics(opt.width, opt.height);

  std::vector<ViewSetup> views;
  auto add = [&](double azimuth_deg, double elevation_deg, double radius) {
    double az = azimuth_deg * kPi / 180, el = elevation_deg * kPi / 180;
    double eye[3] = {kTarget[0] + radius * std::cos(el) * std::cos(az) + rng.uniform(-0.06, 0.06),
                     kTarget[1] + radius * std::cos(el) * std::sin(az) + rng.uniform(-0.06, 0.06),
                     kTarget[2] + radius * std::sin(el) + rng.uniform(-0.06, 0.06)};
    double at[3] = {kTarget[0] + rng.uniform(-0.08, 0.08), kTarget[1] + rng.uniform(-0.08, 0.08),
                    kTarget[2] + rng.uniform(-0.05, 0.05)};
    views.push_back(detail::make_view(intr, eye, at));
  };
  // Forward-facing arc: 80 degrees centred on the -y side, low elevation, ~4.6 m away.
  for (int i = 0; i < opt.arc_views; ++i) {
    double s = opt.arc_views > 1 ? double(i) / (opt.arc_views - 1) : 0.5;
    add(-90.0 - 40.0 + 80.0 * s + rng.uniform(-1.5, 1.5), 16.0 + rng.uniform(-2.0, 2.0), 4.6 + rng.uniform(-0.1, 0.1));
  }
  // Orbit: full circle from a seeded start angle, higher elevation, slightly farther.
  double phase = rng.uniform(0.0, 360.0);
  for (int i = 0; i < opt.orbit_views; ++i) {
    double az = phase + 360.0 * i / std::max(1, opt.orbit_views);
    add(az + rng.uniform(-2.0, 2.0), 34.0 + rng.uniform(-3.0, 3.0), 5.0 + rng.uniform(-0.15, 0.15));
  }
  return views;
}

gs::Status validate(const SynthOptions& o) {
  if (o.width < 8 || o.height < 8 || o.width > gs::io::kMaxImageSide || o.height > gs::io::kMaxImageSide) {
    return gs::invalid_argument("synth: image size " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                " out of range [8, " + std::to_string(gs::io::kMaxImageSide) + "]");
  }
  if (o.arc_views < 0 || o.orbit_views < 0 || o.arc_views + o.orbit_views < 1 || o.arc_views + o.orbit_views > 100000) {
    return gs::invalid_argument("synth: need 1..100000 views in total, got arc_views=" + std::to_string(o.arc_views) +
                                " orbit_views=" + std::to_string(o.orbit_views));
  }
  if (o.num_points < 0 || o.num_points > 10000000) {
    return gs::invalid_argument("synth: num_points=" + std::to_string(o.num_points) + " out of range [0, 1e7]");
  }
  if (!(o.point_noise >= 0.0f) || !std::isfinite(o.point_noise)) {
    return gs::invalid_argument("synth: point_noise must be finite and >= 0");
  }
  if (o.samples_per_axis < 1 || o.samples_per_axis > 16) {
    return gs::invalid_argument("synth: samples_per_axis=" + std::to_string(o.samples_per_axis) + " out of range [1, 16]");
  }
  return gs::Status::Ok();
}

gs::Expected<SynthSummary> generate_impl(const SynthOptions& opt, const std::string& out_dir) {
  using clock = std::chrono::steady_clock;
  auto t0 = clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(clock::now() - t0).count(); };

  auto scene_or = Scene::create(opt.seed);
  if (!scene_or.ok()) return scene_or.status();
  const Scene& scene = *scene_or.value();

  std::vector<ViewSetup> views = make_views(opt);
  const int num_views = int(views.size());
  const int W = opt.width, H = opt.height;
  const bool fisheye = opt.camera == SynthOptions::Camera::kFisheye;
  const double lens_focal = fisheye ? fisheye_focal(W) : 0.0;

  // 1. Render. Parallel over rows inside each view; the jitter depends on (seed, view, pixel).
  std::vector<gs::io::Image8> images(static_cast<size_t>(num_views));
  for (int v = 0; v < num_views; ++v) {
    images[size_t(v)] = scene.render(views[size_t(v)].camera, opt.samples_per_axis,
                                     detail::hash_combine(opt.seed, 0x1000000ULL + uint64_t(v)), opt.threads, lens_focal);
  }
  if (opt.verbose)
    std::fprintf(stderr, "synth: rendered %d %sviews of %dx%d in %.2f s\n", num_views, fisheye ? "fisheye " : "", W, H, elapsed());

  // 2. Sparse points on anything within 10 m of the layout centre: that is where the views overlap.
  long long draws = 0;
  const std::vector<detail::SparsePoint> accepted = detail::sample_sparse_points(
      scene, views, images, opt.num_points, opt.point_noise, opt.seed, opt.threads,
      [](const SceneHit& hit) { return std::hypot(hit.position[0] - kTarget[0], hit.position[1] - kTarget[1]) <= 10.0; },
      &draws, lens_focal);
  if (opt.verbose) {
    size_t obs = 0;
    for (const detail::SparsePoint& c : accepted) obs += c.track.size();
    std::fprintf(stderr, "synth: %zu sparse points (mean track %.2f views) from %lld pixel draws, %.2f s\n",
                 accepted.size(), accepted.empty() ? 0.0 : double(obs) / double(accepted.size()), draws, elapsed());
  }

  // 3. Assemble the COLMAP model: one camera, images in view order, ids from 1.
  const int digits = std::max(4, int(std::to_string(num_views - 1).size()));
  std::vector<std::string> names;
  for (int v = 0; v < num_views; ++v) names.push_back(detail::view_name(v, digits, ".png"));
  gs::io::ColmapModel model = detail::make_colmap_model(views, names, accepted);
  if (fisheye) model.cameras.front() = detail::colmap_fisheye(views.front().camera.intr, lens_focal);

  // 4. Write.
  namespace fs = std::filesystem;
  const fs::path root(out_dir);
  const fs::path images_dir = root / "images";
  std::error_code ec;
  fs::create_directories(images_dir, ec);
  if (ec) return gs::io_error("synth: cannot create " + images_dir.string() + ": " + ec.message());
  // PNG compression dominates writing; encode views in parallel and report the first failure in
  // view order.
  std::vector<gs::Status> written(static_cast<size_t>(num_views));
  gs::platform::ThreadPool pool(opt.threads);
  pool.for_each_index(size_t(num_views), [&](size_t v) {
    written[v] = gs::io::write_png((images_dir / model.images[v].name).string(), images[v]);
  });
  for (const gs::Status& st : written) GS_RETURN_IF_ERROR(st);
  GS_RETURN_IF_ERROR(gs::io::write_colmap_text(model, (root / "sparse" / "0").string()));

  SynthSummary summary;
  summary.num_views = num_views;
  summary.num_points = int(accepted.size());
  summary.seconds = elapsed();
  if (opt.verbose) std::fprintf(stderr, "synth: wrote %s in %.2f s\n", out_dir.c_str(), summary.seconds);
  return summary;
}

}  // namespace

double fisheye_focal(int width) { return width / kPi; }

std::vector<gs::Camera> make_cameras(const SynthOptions& options) {
  std::vector<gs::Camera> cams;
  if (!validate(options).ok()) return cams;
  for (const ViewSetup& v : make_views(options)) cams.push_back(v.camera);
  return cams;
}

gs::Expected<SynthSummary> generate_scene(const SynthOptions& options, const std::string& out_dir) {
  GS_RETURN_IF_ERROR(validate(options));
  if (out_dir.empty()) return gs::invalid_argument("synth: empty output directory");
  // Thread start-up, allocation and filesystem failures surface as exceptions; hbgs reports
  // errors as Status, never by throwing past its API.
  try {
    return generate_impl(options, out_dir);
  } catch (const std::exception& e) {
    return gs::Status(gs::StatusCode::kInternal, std::string("synth: ") + e.what());
  }
}

}  // namespace hbgs::synth
