// SPDX-License-Identifier: MIT
// load_dataset: a COLMAP folder (sparse model + images) -> pinhole views with decoded RGB images.
// Radially/tangentially distorted cameras (SIMPLE_RADIAL, RADIAL, OPENCV) are undistorted on load
// into a PINHOLE camera with the same fx, fy, cx, cy, so the renderer only ever sees pinholes.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <system_error>

#include "../io_util.h"
#include "colmap_internal.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

// A COLMAP camera reduced to pinhole intrinsics plus COLMAP's OpenCV-style distortion terms
// (SIMPLE_RADIAL: k1; RADIAL: k1, k2; OPENCV: k1, k2, p1, p2). All-zero terms: no resampling.
struct CameraPlan {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0;
  int width = 0, height = 0;
  std::vector<float> map;  // [H, W, 2] source pixel position (continuous, pixel centres at +0.5) per output pixel
  bool distorted() const { return k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0; }
};

Status make_plan(const ColmapCamera& cam, const std::string& sparse_dir, CameraPlan* plan) {
  const std::vector<double>& p = cam.params;
  CameraPlan c;
  c.width = cam.width, c.height = cam.height;
  if (cam.model == "PINHOLE") {
    c.fx = p[0], c.fy = p[1], c.cx = p[2], c.cy = p[3];
  } else if (cam.model == "SIMPLE_PINHOLE") {
    c.fx = c.fy = p[0], c.cx = p[1], c.cy = p[2];
  } else if (cam.model == "SIMPLE_RADIAL") {
    c.fx = c.fy = p[0], c.cx = p[1], c.cy = p[2], c.k1 = p[3];
  } else if (cam.model == "RADIAL") {
    c.fx = c.fy = p[0], c.cx = p[1], c.cy = p[2], c.k1 = p[3], c.k2 = p[4];
  } else if (cam.model == "OPENCV") {
    c.fx = p[0], c.fy = p[1], c.cx = p[2], c.cy = p[3], c.k1 = p[4], c.k2 = p[5], c.p1 = p[6], c.p2 = p[7];
  } else {
    return unsupported(sparse_dir + ": camera " + std::to_string(cam.id) + " uses model " + cam.model +
                       ", which hbgs cannot load (supported: PINHOLE, SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV)");
  }
  if (c.distorted()) {
    c.map.resize(size_t(c.width) * size_t(c.height) * 2);
    for (int v = 0; v < c.height; ++v) {
      for (int u = 0; u < c.width; ++u) {
        // Same polynomial as COLMAP's OpenCVCameraModel::Distortion (zero terms for the simpler models).
        const double x = (u + 0.5 - c.cx) / c.fx, y = (v + 0.5 - c.cy) / c.fy;
        const double r2 = x * x + y * y, radial = c.k1 * r2 + c.k2 * r2 * r2;
        const double xd = x + x * radial + 2 * c.p1 * x * y + c.p2 * (r2 + 2 * x * x);
        const double yd = y + y * radial + 2 * c.p2 * x * y + c.p1 * (r2 + 2 * y * y);
        float* m = &c.map[(size_t(v) * size_t(c.width) + size_t(u)) * 2];
        m[0] = float(c.fx * xd + c.cx);
        m[1] = float(c.fy * yd + c.cy);
      }
    }
  }
  *plan = std::move(c);
  return Status::Ok();
}

// Bilinear resampling through the plan's map; positions outside the source rectangle are black.
Image8 undistort(const Image8& src, const CameraPlan& plan) {
  Image8 dst;
  dst.width = src.width, dst.height = src.height, dst.channels = src.channels;
  dst.pixels.assign(src.pixels.size(), 0);
  const int w = src.width, h = src.height, ch = src.channels;
  for (size_t i = 0; i < size_t(w) * size_t(h); ++i) {
    const float px = plan.map[2 * i], py = plan.map[2 * i + 1];
    if (!(px >= 0 && px <= float(w) && py >= 0 && py <= float(h))) continue;
    const float sx = px - 0.5f, sy = py - 0.5f;
    const int x0 = int(std::floor(sx)), y0 = int(std::floor(sy));
    const float ax = sx - float(x0), ay = sy - float(y0);
    const int xa = std::clamp(x0, 0, w - 1), xb = std::clamp(x0 + 1, 0, w - 1);
    const int ya = std::clamp(y0, 0, h - 1), yb = std::clamp(y0 + 1, 0, h - 1);
    const uint8_t* r0 = &src.pixels[size_t(ya) * size_t(w) * size_t(ch)];
    const uint8_t* r1 = &src.pixels[size_t(yb) * size_t(w) * size_t(ch)];
    for (int c = 0; c < ch; ++c) {
      const float top = (1 - ax) * r0[xa * ch + c] + ax * r0[xb * ch + c];
      const float bot = (1 - ax) * r1[xa * ch + c] + ax * r1[xb * ch + c];
      dst.pixels[i * size_t(ch) + size_t(c)] = uint8_t(std::min(255.0f, (1 - ay) * top + ay * bot + 0.5f));
    }
  }
  return dst;
}

// The view's pinhole camera (downscaled to options.max_width) and pose.
Status view_camera(const CameraPlan& plan, const DatasetOptions& options, const ColmapImage& im, DatasetView* view) {
  PinholeIntrinsics& K = view->camera.intr;
  double sx = 1, sy = 1;
  K.width = plan.width, K.height = plan.height;
  if (options.max_width > 0 && plan.width > options.max_width) {
    K.width = options.max_width;
    K.height = std::max(1, int(std::lround(double(plan.height) * options.max_width / plan.width)));
    sx = double(K.width) / plan.width, sy = double(K.height) / plan.height;
  }
  K.fx = float(plan.fx * sx), K.cx = float(plan.cx * sx);
  K.fy = float(plan.fy * sy), K.cy = float(plan.cy * sy);
  view->camera.pose = pose_from_colmap(im.qvec, im.tvec);
  return Status::Ok();
}

Expected<Dataset> load(const std::string& root, const DatasetOptions& options) {
  const std::string sparse_dir = detail::join_path(root, options.sparse_dir);
  const std::string images_dir = detail::join_path(root, options.images_dir);
  if (options.max_width < 0) return invalid_argument("load_dataset: max_width must be >= 0");
  if (options.llffhold < 0) return invalid_argument("load_dataset: llffhold must be >= 0");
  auto model = read_colmap_model(sparse_dir);
  if (!model.ok()) return model.status();
  if (!platform::is_directory(images_dir)) return io_error(images_dir + ": images folder not found");

  std::map<uint32_t, CameraPlan> plans;  // only the cameras some image uses
  for (const ColmapImage& im : model->images) {
    if (plans.count(im.camera_id)) continue;
    const auto cam = std::find_if(model->cameras.begin(), model->cameras.end(),
                                  [&](const ColmapCamera& c) { return c.id == im.camera_id; });
    GS_RETURN_IF_ERROR(make_plan(*cam, sparse_dir, &plans[im.camera_id]));  // exists: read_colmap_* checked the links
  }

  std::vector<const ColmapImage*> order;
  for (const ColmapImage& im : model->images) order.push_back(&im);
  std::sort(order.begin(), order.end(), [](const ColmapImage* a, const ColmapImage* b) { return a->name < b->name; });

  Dataset ds;
  ds.root = root;
  ds.views.reserve(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    const ColmapImage& im = *order[i];
    const CameraPlan& plan = plans.at(im.camera_id);
    const std::string path = detail::join_path(images_dir, im.name);
    if (!platform::file_exists(path)) {
      // A symbolic link that does not resolve (a loop, a missing target) is not "not found": the
      // OS's reason is what the user needs.
      std::error_code ec;
      if (std::filesystem::is_symlink(std::filesystem::symlink_status(path, ec))) {
        auto read = read_image(path, 3);
        return io_error(path + ": image " + std::to_string(im.id) + " of the COLMAP model is a symbolic link that does not resolve (" +
                        (read.ok() ? std::string("unreadable") : read.status().message()) + ")");
      }
      return io_error(path + ": image file not found (image " + std::to_string(im.id) + " of the COLMAP model)");
    }
    const bool is_test = options.llffhold > 0 && i % size_t(options.llffhold) == 0;
    const bool wanted = options.images == DatasetOptions::Images::kAll ||
                        (options.images == DatasetOptions::Images::kTest) == is_test;
    if (!wanted) {  // camera and pose only
      DatasetView view;
      view.name = im.name;
      view.image_id = im.id;
      view.is_test = is_test;
      GS_RETURN_IF_ERROR(view_camera(plan, options, im, &view));
      ds.views.push_back(std::move(view));
      continue;
    }
    auto img = read_image(path, 3);
    if (!img.ok()) return img.status();
    if (img->width != plan.width || img->height != plan.height)
      return invalid_argument(path + ": image is " + std::to_string(img->width) + "x" + std::to_string(img->height) +
                              " but camera " + std::to_string(im.camera_id) + " expects " + std::to_string(plan.width) +
                              "x" + std::to_string(plan.height));

    DatasetView view;
    view.name = im.name;
    view.image_id = im.id;
    view.image = plan.distorted() ? undistort(*img, plan) : std::move(*img);
    GS_RETURN_IF_ERROR(view_camera(plan, options, im, &view));
    if (view.camera.intr.width != plan.width) {
      view.image = resize_area(view.image, view.camera.intr.width, view.camera.intr.height);
      if (view.image.empty()) return Status(StatusCode::kInternal, path + ": downscaling failed");
    }
    view.is_test = is_test;
    ds.views.push_back(std::move(view));
  }

  ds.points_xyz.reserve(model->points.size() * 3);
  ds.points_rgb.reserve(model->points.size() * 3);
  for (const ColmapPoint3D& p : model->points) {
    for (int k = 0; k < 3; ++k) ds.points_xyz.push_back(float(p.xyz[k]));
    for (int k = 0; k < 3; ++k) ds.points_rgb.push_back(p.rgb[k]);
  }
  return ds;
}

}  // namespace

Expected<Dataset> load_dataset(const std::string& root, const DatasetOptions& options) {
  return detail::guarded(root, [&]() { return load(root, options); });
}

}  // namespace gs::io
