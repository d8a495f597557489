// SPDX-License-Identifier: MIT
// generate_object: an object capture (hbgs synth --object). Cameras on the upper hemisphere around
// a small textured subject, rendered with exact coverage (RGBA on a transparent background, or RGB
// on a cluttered one plus masks), written as a COLMAP dataset and as NeRF-style transforms files.
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
#include "gs/io/transforms.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"
#include "hbgs/synth.h"
#include "procedural.h"

namespace hbgs::synth {

double detail::object_camera_distance(const gs::PinholeIntrinsics& K) {
  const double half_x = std::atan(0.5 * K.width / K.fx), half_y = std::atan(0.5 * K.height / K.fy);
  return 1.1 * kObjectRadius / std::sin(std::min(half_x, half_y));
}

namespace {

using gs::kPi;
// Every llffhold-th view (by name) is a test view, as gs::io::DatasetOptions::llffhold splits the
// COLMAP model; the transforms files repeat that split.
constexpr int kTestEvery = 8;

gs::Status validate(const ObjectOptions& o) {
  if (o.width < 8 || o.height < 8 || o.width > gs::io::kMaxImageSide || o.height > gs::io::kMaxImageSide)
    return gs::invalid_argument("synth --object: image size " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                                " out of range [8, " + std::to_string(gs::io::kMaxImageSide) + "]");
  if (2 * o.width < o.height || 2 * o.height < o.width)
    return gs::invalid_argument("synth --object: the image's sides may differ by a factor of 2 at most, got " +
                                std::to_string(o.width) + "x" + std::to_string(o.height));
  if (o.views < 3 || o.views > 100000) return gs::invalid_argument("synth --object: views must be in [3, 100000]");
  if (o.num_points < 0 || o.num_points > 10000000) return gs::invalid_argument("synth --object: num_points out of range [0, 1e7]");
  if (!(o.point_noise >= 0.0f) || !std::isfinite(o.point_noise))
    return gs::invalid_argument("synth --object: point_noise must be finite and >= 0");
  if (o.samples_per_axis < 1 || o.samples_per_axis > 16)
    return gs::invalid_argument("synth --object: samples_per_axis must be in [1, 16]");
  return gs::Status::Ok();
}

std::vector<detail::ViewSetup> make_views(const ObjectOptions& opt) {
  detail::Rng rng(detail::hash_combine(opt.seed, 0x0b1ec7ca3ULL));
  const gs::PinholeIntrinsics intr = detail::synth_intrinsics(opt.width, opt.height);
  const double distance = detail::object_camera_distance(intr);
  std::vector<detail::ViewSetup> views;
  for (int ring = 0; ring < 3; ++ring) {
    const int n = ring < 2 ? opt.views / 3 : opt.views - 2 * (opt.views / 3);
    const double phase = rng.uniform(0.0, 360.0), el = detail::kObjectRingElevationsDeg[ring] * kPi / 180;
    for (int i = 0; i < n; ++i) {
      const double az = (phase + 360.0 * i / n) * kPi / 180;
      const double eye[3] = {kObjectCentre[0] + distance * std::cos(el) * std::cos(az) + rng.uniform(-0.005, 0.005),
                             kObjectCentre[1] + distance * std::cos(el) * std::sin(az) + rng.uniform(-0.005, 0.005),
                             kObjectCentre[2] + distance * std::sin(el) + rng.uniform(-0.005, 0.005)};
      const double at[3] = {kObjectCentre[0] + rng.uniform(-0.005, 0.005), kObjectCentre[1] + rng.uniform(-0.005, 0.005),
                            kObjectCentre[2] + rng.uniform(-0.005, 0.005)};
      views.push_back(detail::make_view(intr, eye, at));
    }
  }
  return views;
}

// transforms_<split>.json for the views of one split (NeRF synthetic's layout with nerfstudio's
// intrinsics keys; see generate_object in hbgs/synth.h).
gs::Status write_transforms(const std::string& path, const std::vector<detail::ViewSetup>& views,
                            const std::vector<std::string>& names, const std::vector<std::string>& mask_names,
                            bool test) {
  const gs::PinholeIntrinsics& K = views.front().camera.intr;
  gs::io::TransformsIntrinsics intrinsics;
  intrinsics.camera_angle_x = 2 * std::atan(0.5 * K.width / double(K.fx));
  intrinsics.fl_x = double(K.fx);
  intrinsics.fl_y = double(K.fy);
  intrinsics.cx = double(K.cx);
  intrinsics.cy = double(K.cy);
  intrinsics.w = K.width;
  intrinsics.h = K.height;
  gs::io::TransformsFile file;
  for (size_t v = 0; v < views.size(); ++v) {
    if ((int(v) % kTestEvery == 0) != test) continue;
    const std::string& name = names[v];
    gs::io::TransformsFrame f;
    f.file_path = "./images/" + name.substr(0, name.rfind('.'));
    if (!mask_names.empty()) f.mask_path = "masks/" + mask_names[v];
    f.intrinsics = intrinsics;
    gs::io::transform_matrix_from_pose(views[v].qvec, views[v].tvec, f.transform_matrix);
    file.frames.push_back(std::move(f));
  }
  return gs::io::write_transforms_json(path, file);
}

// The alpha channel of an RGBA image, as a 1-channel mask.
gs::io::Image8 alpha_of(const gs::io::Image8& rgba) {
  gs::io::Image8 m{rgba.width, rgba.height, 1, std::vector<uint8_t>(size_t(rgba.width) * size_t(rgba.height))};
  for (size_t i = 0; i < m.pixels.size(); ++i) m.pixels[i] = rgba.pixels[4 * i + 3];
  return m;
}

gs::Expected<ObjectSummary> generate_impl(const ObjectOptions& opt, const std::string& out_dir) {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(clock::now() - t0).count(); };
  const bool cluttered = opt.background == ObjectOptions::Background::kCluttered;
  const std::vector<detail::ViewSetup> views = make_views(opt);
  const int num_views = int(views.size());
  auto scene_or = Scene::create_object(opt.seed, cluttered, detail::object_camera_distance(views.front().camera.intr));
  if (!scene_or.ok()) return scene_or.status();
  const Scene& scene = *scene_or.value();

  // 1. Render both layers; the jitter depends on (seed, view, pixel) only.
  const size_t n_views = views.size();
  std::vector<gs::io::Image8> composite(n_views), subject(n_views);
  for (int v = 0; v < num_views; ++v)
    scene.render_layers(views[size_t(v)].camera, opt.samples_per_axis, detail::hash_combine(opt.seed, 0x3000000ULL + uint64_t(v)),
                        opt.threads, cluttered ? &composite[size_t(v)] : nullptr, &subject[size_t(v)]);
  ObjectSummary summary;
  summary.render_seconds = elapsed();
  if (opt.verbose)
    std::fprintf(stderr, "synth --object: rendered %d views of %dx%d (%d samples per pixel) in %.2f s\n", num_views, opt.width,
                 opt.height, opt.samples_per_axis * opt.samples_per_axis, summary.render_seconds);

  // 2. Sparse points on the subject's surface only (the background, if any, is masked out).
  const std::vector<gs::io::Image8>& colours = cluttered ? composite : subject;
  long long draws = 0;
  const std::vector<detail::SparsePoint> points = detail::sample_sparse_points(
      scene, views, colours, opt.num_points, opt.point_noise, detail::hash_combine(opt.seed, 0x0b1ec7ULL), opt.threads,
      [&](const SceneHit& hit) { return scene.is_subject(hit.object); }, &draws);
  if (opt.verbose)
    std::fprintf(stderr, "synth --object: %zu sparse points from %lld pixel draws, %.2f s\n", points.size(), draws, elapsed());

  // 3. Names, the COLMAP model and the files.
  const int digits = std::max(4, int(std::to_string(num_views - 1).size()));
  std::vector<std::string> names, mask_names;
  for (int v = 0; v < num_views; ++v) {
    names.push_back(detail::view_name(v, digits, cluttered ? ".jpg" : ".png"));
    // Transparent: same-name masks (CO3D style); cluttered: COLMAP's <image name>.png.
    mask_names.push_back(cluttered ? names.back() + ".png" : names.back());
  }
  const gs::io::ColmapModel model = detail::make_colmap_model(views, names, points);
  namespace fs = std::filesystem;
  const fs::path root(out_dir);
  for (const char* sub : {"images", "masks"}) GS_RETURN_IF_ERROR(gs::platform::make_dirs((root / sub).string()));
  std::vector<gs::Status> written(n_views);
  gs::platform::ThreadPool pool(opt.threads);
  pool.for_each_index(size_t(num_views), [&](size_t i) {
    const std::string image_path = (root / "images" / names[i]).string();
    gs::Status st = cluttered ? gs::io::write_jpeg(image_path, composite[i], 95) : gs::io::write_png(image_path, subject[i]);
    if (st.ok()) st = gs::io::write_png((root / "masks" / mask_names[i]).string(), alpha_of(subject[i]));
    written[i] = st;
  });
  for (const gs::Status& st : written) GS_RETURN_IF_ERROR(st);
  GS_RETURN_IF_ERROR(gs::io::write_colmap_text(model, (root / "sparse" / "0").string()));
  const std::vector<std::string> frame_masks = cluttered ? mask_names : std::vector<std::string>{};
  GS_RETURN_IF_ERROR(write_transforms((root / "transforms_train.json").string(), views, names, frame_masks, false));
  GS_RETURN_IF_ERROR(write_transforms((root / "transforms_test.json").string(), views, names, frame_masks, true));

  summary.num_views = num_views;
  summary.num_test_views = (num_views + kTestEvery - 1) / kTestEvery;
  summary.num_points = int(points.size());
  summary.seconds = elapsed();
  if (opt.verbose) std::fprintf(stderr, "synth --object: wrote %s in %.2f s\n", out_dir.c_str(), summary.seconds);
  return summary;
}

}  // namespace

std::vector<gs::Camera> make_object_cameras(const ObjectOptions& options) {
  std::vector<gs::Camera> cams;
  if (!validate(options).ok()) return cams;
  for (const detail::ViewSetup& v : make_views(options)) cams.push_back(v.camera);
  return cams;
}

gs::Expected<ObjectSummary> generate_object(const ObjectOptions& options, const std::string& out_dir) {
  GS_RETURN_IF_ERROR(validate(options));
  if (out_dir.empty()) return gs::invalid_argument("synth --object: empty output directory");
  // Thread start-up, allocation and filesystem failures surface as exceptions; hbgs reports
  // errors as Status, never by throwing past its API.
  try {
    return generate_impl(options, out_dir);
  } catch (const std::exception& e) {
    return gs::Status(gs::StatusCode::kInternal, std::string("synth --object: ") + e.what());
  }
}

}  // namespace hbgs::synth
