// SPDX-License-Identifier: MIT
// load_dataset: a COLMAP folder (sparse model + images) or a NeRF-style folder (transforms.json)
// -> pinhole views with decoded RGB images, subject masks (alpha or mask files) and points; and
// read_dataset_files, the same views as their files describe them (for writers of posed models).
// Both layouts become one list of views to load, so undistortion (SIMPLE_RADIAL, RADIAL, OPENCV
// into a PINHOLE camera with the same fx, fy, cx, cy; the fisheye models into a PINHOLE camera of a
// chosen field of view; pixels without a source marked invalid), masks, downscaling and the split
// are done by one implementation and the renderer only ever sees pinholes.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <system_error>

#include "../colmap/colmap_internal.h"
#include "../io_util.h"
#include "gs/bilinear.h"
#include "gs/constants.h"
#include "gs/io/transforms.h"
#include "gs/platform/file.h"
#include "gs/platform/path.h"
#include "gs/pose/pose.h"
#include "gs/scene_frame.h"

namespace gs::io {
namespace {

double degrees(double radians) { return radians * 180 / kPi; }

// How a camera becomes a pinhole view: its stored camera in DatasetFileView's form, the pinhole it
// is loaded as, and (when they differ) each output pixel's position in the stored image.
struct CameraPlan {
  ColmapCamera stored;             // PINHOLE, OPENCV, OPENCV_FISHEYE or FOV (DatasetFileView::camera)
  double fx = 0, fy = 0, cx = 0, cy = 0;  // the pinhole the view is loaded as
  int width = 0, height = 0;       // both images' size
  std::vector<float> map;  // [H, W, 2] source pixel position (continuous, pixel centres at +0.5) per output pixel; NaN: none
  Image8 valid;            // 1 channel, 255 where the map has a source pixel; empty when every pixel has
  bool distorted() const { return !map.empty(); }
};

// Whether a source position lies in the source image (undistort samples it).
bool inside(float px, float py, int w, int h) { return px >= 0 && px <= float(w) && py >= 0 && py <= float(h); }

// The output pixel (u, v)'s camera-space ray through the plan's pinhole.
void pinhole_ray(const CameraPlan& c, int u, int v, double ray[3]) {
  ray[0] = (u + 0.5 - c.cx) / c.fx, ray[1] = (v + 0.5 - c.cy) / c.fy, ray[2] = 1;
}

// Whether every pixel of a w x h pinhole of horizontal field of view fov (radians, centred) has a
// source pixel in the fisheye camera: within its valid angle and inside its image. The border
// pixels decide (the radius grows with the angle, so the border's image encloses the rest).
bool fisheye_fov_fits(const ColmapCamera& cam, double valid_angle, double fov) {
  const int w = cam.width, h = cam.height;
  const double f = 0.5 * w / std::tan(0.5 * fov), cx = 0.5 * w, cy = 0.5 * h;
  auto fits = [&](int u, int v) {
    const double ray[3] = {(u + 0.5 - cx) / f, (v + 0.5 - cy) / f, 1};
    if (std::atan(std::hypot(ray[0], ray[1])) > valid_angle) return false;
    double pu = 0, pv = 0;
    return colmap_project(cam, ray, &pu, &pv) && std::fabs(pu) < 1e9 && std::fabs(pv) < 1e9 && inside(float(pu), float(pv), w, h);
  };
  for (int u = 0; u < w; ++u)
    if (!fits(u, 0) || !fits(u, h - 1)) return false;
  for (int v = 0; v < h; ++v)
    if (!fits(0, v) || !fits(w - 1, v)) return false;
  return true;
}

// The fisheye camera's pinhole: options.fisheye_fov_deg, or the widest fitting one up to
// kDefaultFisheyeFovDeg (to 0.01 degree, rounded down). Refuses a lens whose radius stops growing
// within the angles the pinhole needs.
// `model`: the camera's model as stored (cam is in DatasetFileView's form).
Status plan_fisheye(const ColmapCamera& cam, const std::string& model, const std::string& where, const DatasetOptions& options,
                    CameraPlan* c) {
  const double valid_angle = fisheye_valid_angle(cam);
  const std::string named = where + " (" + model + ")";
  if (!(valid_angle > kPi / 180))
    return invalid_argument(named + ": the lens's radius does not grow with the angle from the axis even below 1 degree (" +
                            (cam.model == "FOV" ? "FOV's omega must be below pi in magnitude" : "the distortion polynomial falls from the start") + ")");
  const int w = cam.width, h = cam.height;
  // The widest field of view whose corner pixels' centres stay within valid_angle (centred pinhole,
  // square pixels), as fisheye_fov_fits and the map judge them.
  const double half_diagonal_ratio = std::max(1e-9, std::hypot(0.5 * w - 0.5, 0.5 * h - 0.5)) / (0.5 * w);
  const double widest = 2 * std::atan(std::tan(std::min(valid_angle, 0.5 * kPi - 1e-9)) / half_diagonal_ratio);
  double fov = options.fisheye_fov_deg * kPi / 180;
  if (fov > 0) {
    if (fov > widest + 1e-12) {
      const double corner = std::atan(std::tan(0.5 * fov) * half_diagonal_ratio);
      return invalid_argument(named + ": the lens's radius stops growing " + std::to_string(degrees(valid_angle)) +
                              " degrees from the axis, but a pinhole of " + std::to_string(options.fisheye_fov_deg) +
                              " degrees needs rays up to " + std::to_string(degrees(corner)) +
                              " degrees; pass a fisheye field of view of at most " +
                              std::to_string(std::floor(degrees(widest) * 100) / 100) + " degrees");
    }
  } else {
    const double cap = kDefaultFisheyeFovDeg * kPi / 180;
    if (fisheye_fov_fits(cam, valid_angle, cap)) {
      fov = cap;
    } else {
      double lo = 0, hi = cap;
      for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        (fisheye_fov_fits(cam, valid_angle, mid) ? lo : hi) = mid;
      }
      fov = std::floor(degrees(lo) * 100) / 100 * kPi / 180;
      if (!(fov >= kPi / 180))
        return invalid_argument(named + ": no pinhole of 1 degree or more fits inside the image (is the principal point "
                                "inside it?); pass a fisheye field of view");
    }
  }
  c->fx = c->fy = 0.5 * w / std::tan(0.5 * fov);
  c->cx = 0.5 * w, c->cy = 0.5 * h;
  c->map.resize(size_t(w) * size_t(h) * 2);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      double ray[3], pu = 0, pv = 0;
      pinhole_ray(*c, u, v, ray);
      float* m = &c->map[(size_t(v) * size_t(w) + size_t(u)) * 2];
      m[0] = m[1] = std::numeric_limits<float>::quiet_NaN();
      if (std::atan(std::hypot(ray[0], ray[1])) <= valid_angle && colmap_project(cam, ray, &pu, &pv) &&
          std::fabs(pu) < 1e9 && std::fabs(pv) < 1e9)  // (far outside: none; and float can hold it)
        m[0] = float(pu), m[1] = float(pv);
    }
  }
  return Status::Ok();
}

// `where` names the camera in errors ("<sparse dir>/cameras.txt: camera 3", "<json>: frame 2").
Status make_plan(const ColmapCamera& cam, const std::string& where, const DatasetOptions& options, CameraPlan* plan) {
  const std::vector<double>& p = cam.params;
  CameraPlan c;
  c.width = cam.width, c.height = cam.height;
  c.stored.id = cam.id, c.stored.width = cam.width, c.stored.height = cam.height;
  if (cam.model == "PINHOLE") {
    c.stored.params = {p[0], p[1], p[2], p[3]};
  } else if (cam.model == "SIMPLE_PINHOLE") {
    c.stored.params = {p[0], p[0], p[1], p[2]};
  } else if (cam.model == "SIMPLE_RADIAL") {
    c.stored.params = {p[0], p[0], p[1], p[2], p[3], 0, 0, 0};
  } else if (cam.model == "RADIAL") {
    c.stored.params = {p[0], p[0], p[1], p[2], p[3], p[4], 0, 0};
  } else if (cam.model == "OPENCV" || cam.model == "OPENCV_FISHEYE" || cam.model == "FOV") {
    c.stored.params = p;
  } else if (cam.model == "RADIAL_FISHEYE") {
    c.stored.params = {p[0], p[0], p[1], p[2], p[3], p[4], 0, 0};
  } else if (cam.model == "SIMPLE_RADIAL_FISHEYE") {
    c.stored.params = {p[0], p[0], p[1], p[2], p[3], 0, 0, 0};
  } else {
    return unsupported(where + " uses model " + cam.model +
                       ", which hbgs cannot load (supported: PINHOLE, SIMPLE_PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, "
                       "OPENCV_FISHEYE, RADIAL_FISHEYE, SIMPLE_RADIAL_FISHEYE, FOV)");
  }
  const std::vector<double>& q = c.stored.params;
  const bool fisheye = is_fisheye_model(cam.model);
  c.stored.model = fisheye ? (cam.model == "FOV" ? "FOV" : "OPENCV_FISHEYE")
                           : (q.size() == 8 && (q[4] != 0 || q[5] != 0 || q[6] != 0 || q[7] != 0)) ? "OPENCV" : "PINHOLE";
  if (c.stored.model == "PINHOLE") c.stored.params.resize(4);
  if (fisheye) {
    GS_RETURN_IF_ERROR(plan_fisheye(c.stored, cam.model, where, options, &c));
  } else {
    c.fx = q[0], c.fy = q[1], c.cx = q[2], c.cy = q[3];
    if (c.stored.model == "OPENCV") {  // colmap_project's OpenCV polynomial at each pixel's pinhole ray
      c.map.resize(size_t(c.width) * size_t(c.height) * 2);
      for (int v = 0; v < c.height; ++v) {
        for (int u = 0; u < c.width; ++u) {
          double ray[3], pu = 0, pv = 0;
          pinhole_ray(c, u, v, ray);
          colmap_project(c.stored, ray, &pu, &pv);
          float* m = &c.map[(size_t(v) * size_t(c.width) + size_t(u)) * 2];
          m[0] = float(pu), m[1] = float(pv);
        }
      }
    }
  }
  if (c.distorted()) {  // which pixels have a source pixel (kept only when some have none)
    const size_t n = size_t(c.width) * size_t(c.height);
    c.valid = {c.width, c.height, 1, std::vector<uint8_t>(n, 255)};
    bool all = true;
    for (size_t i = 0; i < n; ++i)
      if (!inside(c.map[2 * i], c.map[2 * i + 1], c.width, c.height)) c.valid.pixels[i] = 0, all = false;
    if (all) c.valid = Image8{};
  }
  *plan = std::move(c);
  return Status::Ok();
}

// Bilinear resampling (gs/bilinear.h, in float) through the plan's map, any channel count (images
// and masks take the same path); positions outside the source rectangle (or without one) are 0.
Image8 undistort(const Image8& src, const CameraPlan& plan) {
  Image8 dst;
  dst.width = src.width, dst.height = src.height, dst.channels = src.channels;
  dst.pixels.assign(src.pixels.size(), 0);
  const int w = src.width, h = src.height, ch = src.channels;
  for (size_t i = 0; i < size_t(w) * size_t(h); ++i) {
    const float px = plan.map[2 * i], py = plan.map[2 * i + 1];
    if (!inside(px, py, w, h)) continue;
    const BilinearCell<float> q = bilinear_cell(px - 0.5f, py - 0.5f, w, h);
    const uint8_t* r0 = &src.pixels[size_t(q.y0) * size_t(w) * size_t(ch)];
    const uint8_t* r1 = &src.pixels[size_t(q.y1) * size_t(w) * size_t(ch)];
    for (int c = 0; c < ch; ++c) {
      const float v = bilinear_blend(q, r0[q.x0 * ch + c], r0[q.x1 * ch + c], r1[q.x0 * ch + c], r1[q.x1 * ch + c]);
      dst.pixels[i * size_t(ch) + size_t(c)] = uint8_t(std::min(255.0f, v + 0.5f));
    }
  }
  return dst;
}

// One view to load, from either layout.
struct ViewSpec {
  std::string name;        // the view's name: COLMAP image name, or path relative to the json
  std::string image_path;  // the file to read
  std::string mask_path;   // an explicit mask file (nerfstudio "mask_path"); "" = look in masks_dir
  std::string what;        // how errors name the view ("image 3 of the COLMAP model")
  uint32_t image_id = 0;
  size_t plan = 0;  // index into Source::plans
  double qvec[4] = {1, 0, 0, 0}, tvec[3] = {0, 0, 0};
  enum class Split { kByName, kTrain, kTest } split = Split::kByName;
  bool transforms = false;  // from a transforms file (mask lookup also without the first folder)
};

struct Source {
  DatasetLayout layout = DatasetLayout::kColmap;
  std::vector<CameraPlan> plans;
  std::vector<ViewSpec> views;
  std::vector<double> points_xyz;  // user units, double until the scene frame is applied
  std::vector<uint8_t> points_rgb;
  PointsSource points_source = PointsSource::kSfm;
  bool masks_named = false;  // every view names its mask file: masks_dir is not searched
};

// ---- COLMAP layout ----

// `keep` (optional) receives the model as read.
Expected<Source> colmap_source(const std::string& root, const DatasetOptions& options, ColmapModel* keep) {
  const std::string sparse_dir = detail::join_path(root, options.sparse_dir);
  const std::string images_dir = detail::join_path(root, options.images_dir);
  auto model = read_colmap_model(sparse_dir);
  if (!model.ok()) return model.status();
  if (!platform::is_directory(images_dir)) return io_error(images_dir + ": images folder not found");
  Source src;
  src.layout = DatasetLayout::kColmap;
  std::map<uint32_t, size_t> plan_of_camera;  // only the cameras some image uses
  // The file the cameras were read from (read_colmap_model takes the .bin set when it is complete).
  bool binary = true;
  for (const char* f : {"cameras.bin", "images.bin", "points3D.bin"}) binary = binary && platform::file_exists(detail::join_path(sparse_dir, f));
  const std::string cameras_file = detail::join_path(sparse_dir, binary ? "cameras.bin" : "cameras.txt");
  for (const ColmapImage& im : model->images) {
    if (plan_of_camera.count(im.camera_id)) continue;
    const auto cam = std::find_if(model->cameras.begin(), model->cameras.end(),
                                  [&](const ColmapCamera& c) { return c.id == im.camera_id; });
    CameraPlan plan;  // the camera exists: read_colmap_* checked the links
    GS_RETURN_IF_ERROR(make_plan(*cam, cameras_file + ": camera " + std::to_string(cam->id), options, &plan));
    plan_of_camera[im.camera_id] = src.plans.size();
    src.plans.push_back(std::move(plan));
  }
  for (const ColmapImage& im : model->images) {
    ViewSpec v;
    v.name = im.name;
    v.image_path = detail::join_path(images_dir, im.name);
    v.what = "image " + std::to_string(im.id) + " of the COLMAP model";
    v.image_id = im.id;
    v.plan = plan_of_camera.at(im.camera_id);
    std::copy(im.qvec, im.qvec + 4, v.qvec);
    std::copy(im.tvec, im.tvec + 3, v.tvec);
    src.views.push_back(std::move(v));
  }
  src.points_xyz.reserve(model->points.size() * 3);
  src.points_rgb.reserve(model->points.size() * 3);
  for (const ColmapPoint3D& p : model->points) {
    for (int k = 0; k < 3; ++k) src.points_xyz.push_back(p.xyz[k]);
    for (int k = 0; k < 3; ++k) src.points_rgb.push_back(p.rgb[k]);
  }
  src.points_source = PointsSource::kSfm;
  if (keep) *keep = std::move(model).value();
  return src;
}

// ---- Transforms layout ----

// A path from a transforms file as a name below its folder: refused when absolute or with a '..'
// component (platform::relative_name_problem, as for COLMAP image names); "." components and
// repeated slashes dropped ("./train/r_0" -> "train/r_0").
Status clean_relative_path(const std::string& raw, const std::string& at, const char* key, std::string* out) {
  if (std::string why = platform::relative_name_problem(raw); !why.empty())
    return invalid_argument(at + "'" + key + "' is '" + raw + "', which cannot be a file below the dataset folder: " + why);
  std::string name;
  size_t start = 0;
  while (start <= raw.size()) {
    const size_t slash = std::min(raw.find('/', start), raw.size());
    const std::string part = raw.substr(start, slash - start);
    if (!part.empty() && part != ".") name += (name.empty() ? "" : "/") + part;
    start = slash + 1;
  }
  if (name.empty()) return invalid_argument(at + "'" + key + "' is '" + raw + "', which names no file");
  *out = name;
  return Status::Ok();
}

// The image file of a frame: the name as written, else with .png, .jpg or .jpeg appended (NeRF's
// synthetic scenes write "./train/r_0" for train/r_0.png).
Status find_frame_image(const std::string& folder, const std::string& name, const std::string& at, std::string* resolved) {
  for (const char* ext : {"", ".png", ".jpg", ".jpeg"}) {
    const std::string candidate = name + ext;
    if (platform::file_exists(detail::join_path(folder, candidate))) {
      *resolved = candidate;
      return Status::Ok();
    }
  }
  return io_error(at + "image file " + detail::join_path(folder, name) + " not found (nor with .png, .jpg or .jpeg appended)");
}

// Pixel intrinsics of a frame whose image is width x height (the json's w, h or the file's size).
ColmapCamera frame_camera(const TransformsIntrinsics& in, int width, int height) {
  ColmapCamera cam;
  cam.width = width, cam.height = height;
  double fx = 0, fy = 0;
  if (in.fl_x) fx = *in.fl_x;
  else if (in.camera_angle_x) fx = 0.5 * width / std::tan(0.5 * *in.camera_angle_x);
  if (in.fl_y) fy = *in.fl_y;
  else if (in.camera_angle_y) fy = 0.5 * height / std::tan(0.5 * *in.camera_angle_y);
  if (fx == 0) fx = fy;
  if (fy == 0) fy = fx;
  const double cx = in.cx ? *in.cx : width / 2.0, cy = in.cy ? *in.cy : height / 2.0;
  const double k1 = in.k1.value_or(0), k2 = in.k2.value_or(0), p1 = in.p1.value_or(0), p2 = in.p2.value_or(0);
  if (k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0) {
    cam.model = "OPENCV";
    cam.params = {fx, fy, cx, cy, k1, k2, p1, p2};
  } else {
    cam.model = "PINHOLE";
    cam.params = {fx, fy, cx, cy};
  }
  return cam;
}

struct TransformsInput {
  std::string path;  // the json file
  ViewSpec::Split split = ViewSpec::Split::kByName;
};

// Matches a split list's entries to frames (by cleaned path, with or without the resolved
// extension); the indices of those views in Source::views.
Status split_indices(const std::vector<std::string>& list, const char* key, const std::string& source,
                     const std::map<std::string, size_t>& by_name, std::set<size_t>* out) {
  for (const std::string& entry : list) {
    std::string name;
    GS_RETURN_IF_ERROR(clean_relative_path(entry, source + ": ", key, &name));
    const auto it = by_name.find(name);
    if (it == by_name.end())
      return invalid_argument(source + ": '" + key + "' names '" + entry + "', which is not the file_path of any frame");
    out->insert(it->second);
  }
  return Status::Ok();
}

Expected<Source> transforms_source(const std::string& folder, const std::vector<TransformsInput>& inputs,
                                   const DatasetOptions& options) {
  Source src;
  src.layout = DatasetLayout::kTransforms;
  std::map<std::vector<double>, size_t> plan_of_camera;  // (w, h, model params) -> plan
  std::map<std::string, std::string> frame_of_name;      // resolved name -> "frame i of file"
  std::map<std::string, size_t> view_of_name;            // cleaned and resolved names -> index in src.views
  std::string ply;                                       // the first file's ply_file_path
  std::string ply_source;
  std::optional<std::vector<std::string>> train_list, val_list, test_list;
  for (const TransformsInput& input : inputs) {
    auto text = platform::read_text_file(input.path, uint64_t(1) << 30);
    if (!text.ok()) return text.status();
    TransformsFile file;
    GS_RETURN_IF_ERROR(parse_transforms_json(*text, input.path, &file));
    if (ply.empty() && !file.ply_file_path.empty()) ply = file.ply_file_path, ply_source = input.path;
    if (inputs.size() == 1) train_list = file.train_filenames, val_list = file.val_filenames, test_list = file.test_filenames;
    int first_w = 0, first_h = 0;  // sizes of the file's images when it gives no w, h
    for (size_t i = 0; i < file.frames.size(); ++i) {
      const TransformsFrame& f = file.frames[i];
      const std::string at = input.path + ": frame " + std::to_string(i) + ": ";
      ViewSpec v;
      std::string cleaned;
      GS_RETURN_IF_ERROR(clean_relative_path(f.file_path, at, "file_path", &cleaned));
      GS_RETURN_IF_ERROR(find_frame_image(folder, cleaned, at, &v.name));
      const std::string where = "frame " + std::to_string(i) + " of " + input.path;
      if (const auto [it, fresh] = frame_of_name.emplace(v.name, where); !fresh)
        return invalid_argument(at + "names the image " + v.name + ", as " + it->second + " does");
      v.image_path = detail::join_path(folder, v.name);
      v.what = where;
      v.image_id = uint32_t(src.views.size() + 1);
      v.split = input.split;
      v.transforms = true;
      if (!f.mask_path.empty()) {
        std::string mask;
        GS_RETURN_IF_ERROR(clean_relative_path(f.mask_path, at, "mask_path", &mask));
        v.mask_path = detail::join_path(folder, mask);
      }
      int width = f.intrinsics.w.value_or(0), height = f.intrinsics.h.value_or(0);
      if (width == 0 || height == 0) {
        auto info = read_image_info(v.image_path);
        if (!info.ok()) return info.status();
        if (first_w == 0) first_w = info->width, first_h = info->height;
        if (info->width != first_w || info->height != first_h)
          return invalid_argument(at + v.image_path + " is " + std::to_string(info->width) + "x" + std::to_string(info->height) +
                                  " but frame 0's image is " + std::to_string(first_w) + "x" + std::to_string(first_h) +
                                  " (the file gives no w and h, so all its images must have one size)");
        if (width == 0) width = info->width;
        if (height == 0) height = info->height;
      }
      if (!f.intrinsics.fl_x && !f.intrinsics.fl_y && !f.intrinsics.camera_angle_x && !f.intrinsics.camera_angle_y)
        return invalid_argument(at + "no focal length (fl_x, fl_y, camera_angle_x or camera_angle_y, in the frame or at the top level)");
      ColmapCamera cam = frame_camera(f.intrinsics, width, height);
      if (std::string why = detail::check_camera(cam); !why.empty()) return invalid_argument(at + why);
      std::vector<double> key = {double(width), double(height)};
      key.insert(key.end(), cam.params.begin(), cam.params.end());
      auto [plan_it, new_camera] = plan_of_camera.emplace(key, src.plans.size());
      if (new_camera) {
        CameraPlan plan;
        GS_RETURN_IF_ERROR(make_plan(cam, input.path + ": frame " + std::to_string(i), options, &plan));
        src.plans.push_back(std::move(plan));
      }
      v.plan = plan_it->second;
      if (std::string why = pose_from_transform_matrix(f.transform_matrix, v.qvec, v.tvec); !why.empty())
        return invalid_argument(at + "'transform_matrix' is not a camera pose: " + why);  // parse checked it already
      view_of_name.emplace(cleaned, src.views.size());
      view_of_name.emplace(v.name, src.views.size());
      src.views.push_back(std::move(v));
    }
  }
  // Frames that name their masks (nerfstudio's mask_path) all do, as nerfstudio requires; then the
  // masks folder is not searched.
  const auto named = std::find_if(src.views.begin(), src.views.end(), [](const ViewSpec& v) { return !v.mask_path.empty(); });
  if (named != src.views.end()) {
    for (const ViewSpec& v : src.views)
      if (v.mask_path.empty())
        return invalid_argument(v.what + ": no 'mask_path', but " + named->what + " has one (give every frame a mask_path, or none)");
    src.masks_named = true;
  }
  // One file's split lists: test = test_filenames, else val_filenames; train = train_filenames, else
  // every other frame. Frames in neither list are not views of the dataset.
  if (test_list || val_list || train_list) {
    const std::string& source = inputs.front().path;
    std::set<size_t> test, train;
    if (test_list) GS_RETURN_IF_ERROR(split_indices(*test_list, "test_filenames", source, view_of_name, &test));
    else if (val_list) GS_RETURN_IF_ERROR(split_indices(*val_list, "val_filenames", source, view_of_name, &test));
    if (train_list) GS_RETURN_IF_ERROR(split_indices(*train_list, "train_filenames", source, view_of_name, &train));
    std::vector<ViewSpec> kept;
    for (size_t i = 0; i < src.views.size(); ++i) {
      ViewSpec& v = src.views[i];
      if (test.count(i) && train.count(i))
        return invalid_argument(source + ": " + v.name + " is in both the training and the test list");
      if (test.count(i)) v.split = ViewSpec::Split::kTest;
      else if (!train_list || train.count(i)) v.split = ViewSpec::Split::kTrain;
      else continue;
      kept.push_back(std::move(v));
    }
    src.views = std::move(kept);
    if (src.views.empty()) return invalid_argument(source + ": the split lists leave no frames");
  }
  if (!ply.empty()) {
    std::string name;
    GS_RETURN_IF_ERROR(clean_relative_path(ply, ply_source + ": ", "ply_file_path", &name));
    auto cloud = read_point_ply(detail::join_path(folder, name));
    if (!cloud.ok()) return cloud.status();
    src.points_xyz.assign(cloud->xyz.begin(), cloud->xyz.end());
    src.points_rgb = std::move(cloud->rgb);
    src.points_source = PointsSource::kPly;
  } else {
    src.points_source = PointsSource::kRandom;  // drawn once the cameras are known
  }
  return src;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// The transforms files of a folder: transforms.json, or the NeRF synthetic train + test pair.
std::vector<TransformsInput> transforms_inputs(const std::string& folder) {
  const std::string one = detail::join_path(folder, "transforms.json");
  if (platform::file_exists(one)) return {{one, ViewSpec::Split::kByName}};
  const std::string train = detail::join_path(folder, "transforms_train.json");
  if (!platform::file_exists(train)) return {};
  std::vector<TransformsInput> inputs = {{train, ViewSpec::Split::kTrain}};
  const std::string test = detail::join_path(folder, "transforms_test.json");
  if (platform::file_exists(test)) inputs.push_back({test, ViewSpec::Split::kTest});
  else inputs.front().split = ViewSpec::Split::kByName;  // no test file: every llffhold-th view
  return inputs;
}

// ---- Masks ----

// A mask file as 1 channel: grey level composited over black (see load_dataset); 0/1 files scaled.
Expected<Image8> read_mask(const std::string& path) {
  auto rgba = read_image(path, 4);
  if (!rgba.ok()) return rgba.status();
  Image8 m;
  m.width = rgba->width, m.height = rgba->height, m.channels = 1;
  m.pixels.resize(size_t(m.width) * size_t(m.height));
  uint8_t top = 0;
  for (size_t i = 0; i < m.pixels.size(); ++i) {
    const uint8_t* p = &rgba->pixels[4 * i];
    const unsigned lum = (77u * p[0] + 150u * p[1] + 29u * p[2]) >> 8;  // exact for grey: 77 + 150 + 29 = 256
    m.pixels[i] = uint8_t((lum * p[3] + 127u) / 255u);
    top = std::max(top, m.pixels[i]);
  }
  if (top == 1)
    for (uint8_t& v : m.pixels) v = uint8_t(v * 255);
  return m;
}

// The mask file of a view in the masks folder, "" when there is none: NAME.png, NAME, NAME with its
// extension replaced by .png; for a transforms view also the same with NAME's first folder dropped
// (its path is relative to the json: images/x.png has its mask in masks/x.png).
std::string find_mask_file(const std::string& masks_root, const std::string& name, bool drop_first_folder, std::string* tried) {
  std::vector<std::string> names = {name};
  if (const size_t first = name.find('/'); drop_first_folder && first != std::string::npos) names.push_back(name.substr(first + 1));
  std::vector<std::string> candidates;
  for (const std::string& n : names) {
    candidates.push_back(n + ".png");
    candidates.push_back(n);
    const size_t slash = n.rfind('/'), dot = n.rfind('.');
    if (dot != std::string::npos && (slash == std::string::npos || dot > slash) && n.substr(dot) != ".png")
      candidates.push_back(n.substr(0, dot) + ".png");
  }
  for (const std::string& c : candidates) {
    const std::string path = detail::join_path(masks_root, c);
    if (platform::file_exists(path) && !platform::is_directory(path)) return path;
    *tried += (tried->empty() ? "" : ", ") + path;
  }
  return "";
}

// The mask file of a view: its own (mask_path) or the one found in masks_root ("" when not searched);
// "" when there is none, with the paths tried in *tried.
std::string view_mask_file(const ViewSpec& spec, const std::string& masks_root, std::string* tried) {
  if (!spec.mask_path.empty() || masks_root.empty()) return spec.mask_path;
  return find_mask_file(masks_root, spec.name, spec.transforms, tried);
}

// ---- Assembly ----

// The view's pinhole camera (downscaled to options.max_width) and pose.
void view_camera(const CameraPlan& plan, const DatasetOptions& options, const ViewSpec& spec, const SceneFrame& frame,
                 DatasetView* view) {
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
  double R[9];
  pose::rotation_from_quaternion(spec.qvec, R);
  view->camera.pose = pose_to_frame(frame, R, spec.tvec);  // the identity frame: pose_from_colmap's pose
}

// The scene frame of the views' cameras (gs/scene_frame.h), from their stored double poses.
SceneFrame views_frame(const Source& src) {
  std::vector<double> centres(src.views.size() * 3);
  for (size_t i = 0; i < src.views.size(); ++i) {
    double R[9];
    pose::rotation_from_quaternion(src.views[i].qvec, R);
    const double* t = src.views[i].tvec;
    for (int k = 0; k < 3; ++k) centres[3 * i + k] = -(R[k] * t[0] + R[3 + k] * t[1] + R[6 + k] * t[2]);
  }
  return choose_scene_frame(centres.data(), src.views.size());
}

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// Reads a view's image and mask, undistorts and downscales both.
Status load_pixels(const ViewSpec& spec, const CameraPlan& plan, const std::string& masks_root, DatasetView* view) {
  const std::string& path = spec.image_path;
  auto img = read_image(path, kChannelsAsStored);
  if (!img.ok()) return img.status();
  if (img->width != plan.width || img->height != plan.height)
    return invalid_argument(path + ": image is " + size_text(img->width, img->height) + " but its camera (" + spec.what +
                            ") expects " + size_text(plan.width, plan.height));
  Image8 rgb, mask;
  if (img->channels == 4) {  // RGB stays as stored; alpha is the subject's coverage
    const size_t n = size_t(img->width) * size_t(img->height);
    rgb = {img->width, img->height, 3, std::vector<uint8_t>(3 * n)};
    mask = {img->width, img->height, 1, std::vector<uint8_t>(n)};
    for (size_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) rgb.pixels[3 * i + size_t(c)] = img->pixels[4 * i + size_t(c)];
      mask.pixels[i] = img->pixels[4 * i + 3];
    }
  } else {
    rgb = std::move(*img);
  }
  std::string tried;
  const std::string mask_file = view_mask_file(spec, masks_root, &tried);
  if (mask_file.empty() && !masks_root.empty())
    return io_error(masks_root + ": no mask for " + spec.name + " (" + spec.what + "); tried " + tried +
                    ". Every view needs a mask when the dataset has a masks folder");
  if (!mask_file.empty()) {
    auto file_mask = read_mask(mask_file);
    if (!file_mask.ok()) return file_mask.status();
    if (file_mask->width != rgb.width || file_mask->height != rgb.height)
      return invalid_argument(mask_file + ": mask is " + size_text(file_mask->width, file_mask->height) + " but its image " + path +
                              " is " + size_text(rgb.width, rgb.height));
    if (mask.empty()) {
      mask = std::move(*file_mask);
    } else {  // both: their intersection, min (see load_dataset)
      for (size_t i = 0; i < mask.pixels.size(); ++i) mask.pixels[i] = std::min(mask.pixels[i], file_mask->pixels[i]);
    }
  }
  if (plan.distorted()) {
    rgb = undistort(rgb, plan);
    if (!mask.empty()) mask = undistort(mask, plan);
  }
  Image8 valid = plan.valid;
  const int W = view->camera.intr.width, H = view->camera.intr.height;
  if (W != plan.width || H != plan.height) {
    const bool has_mask = !mask.empty(), has_valid = !valid.empty();
    rgb = resize_area(rgb, W, H);
    if (has_mask) mask = resize_area(mask, W, H);
    if (has_valid) {  // valid where the area mean rounds to 255 (over 99.8 % of the pixel's area has a source)
      valid = resize_area(valid, W, H);
      for (uint8_t& v : valid.pixels) v = v == 255 ? 255 : 0;
    }
    if (rgb.empty() || (has_mask && mask.empty()) || (has_valid && valid.empty()))
      return Status(StatusCode::kInternal, path + ": downscaling failed");
  }
  view->image = std::move(rgb);
  view->mask = std::move(mask);
  view->valid = std::move(valid);
  return Status::Ok();
}

// Sorts the views by name, the order of Dataset::views and the one the by-name split counts in.
void sort_views(Source* src) {
  std::sort(src->views.begin(), src->views.end(), [](const ViewSpec& a, const ViewSpec& b) { return a.name < b.name; });
}

// Whether the i-th view by name is a test view: its file's split, else every llffhold-th.
bool is_test_view(const ViewSpec& spec, size_t i, const DatasetOptions& options) {
  return spec.split == ViewSpec::Split::kTest ||
         (spec.split == ViewSpec::Split::kByName && options.llffhold > 0 && i % size_t(options.llffhold) == 0);
}

// The masks folder searched for the views' masks; "" when none is (no such folder, masks_dir "", or
// every frame names its mask).
std::string searched_masks_folder(const Source& src, const std::string& folder, const DatasetOptions& options) {
  if (src.masks_named || options.masks_dir.empty()) return "";
  const std::string masks_root = detail::join_path(folder, options.masks_dir);
  return platform::is_directory(masks_root) ? masks_root : "";
}

Expected<Dataset> assemble(const std::string& root, const std::string& folder, Source src, const DatasetOptions& options) {
  sort_views(&src);
  const std::string masks_root = searched_masks_folder(src, folder, options);

  Dataset ds;
  ds.root = root;
  ds.layout = src.layout;
  ds.frame = options.frame ? *options.frame : views_frame(src);
  if (const char* why = scene_frame_problem(ds.frame); *why) return invalid_argument(root + ": " + why);
  ds.views.reserve(src.views.size());
  for (size_t i = 0; i < src.views.size(); ++i) {
    const ViewSpec& spec = src.views[i];
    const CameraPlan& plan = src.plans.at(spec.plan);
    const std::string& path = spec.image_path;
    if (!platform::file_exists(path)) {
      // A symbolic link that does not resolve (a loop, a missing target) is not "not found": the
      // OS's reason is what the user needs.
      std::error_code ec;
      if (std::filesystem::is_symlink(std::filesystem::symlink_status(path, ec))) {
        auto read = read_image(path, 3);
        return io_error(path + ": " + spec.what + " is a symbolic link that does not resolve (" +
                        (read.ok() ? std::string("unreadable") : read.status().message()) + ")");
      }
      return io_error(path + ": image file not found (" + spec.what + ")");
    }
    DatasetView view;
    view.name = spec.name;
    view.image_id = spec.image_id;
    view.is_test = is_test_view(spec, i, options);
    view_camera(plan, options, spec, ds.frame, &view);
    const bool wanted = options.images == DatasetOptions::Images::kAll ||
                        (options.images == DatasetOptions::Images::kTest) == view.is_test;
    if (wanted) GS_RETURN_IF_ERROR(load_pixels(spec, plan, masks_root, &view));
    ds.views.push_back(std::move(view));
  }

  ds.points_source = src.points_source;
  ds.points_xyz.resize(src.points_xyz.size());
  for (size_t i = 0; i + 2 < src.points_xyz.size(); i += 3) {
    double x[3];
    point_to_frame(ds.frame, &src.points_xyz[i], x);
    for (int k = 0; k < 3; ++k) ds.points_xyz[i + size_t(k)] = float(x[k]);
  }
  ds.points_rgb = std::move(src.points_rgb);
  if (src.points_source == PointsSource::kRandom) {
    if (options.random_points == 0) {
      ds.points_source = PointsSource::kNone;
    } else {
      std::vector<Camera> cameras;
      for (const DatasetView& v : ds.views) cameras.push_back(v.camera);
      auto random = random_points_in_common_view(cameras, size_t(options.random_points), options.random_points_seed);
      if (!random.ok()) return Status(random.status().code(), root + ": " + random.status().message());
      ds.points_xyz = std::move(random->xyz);
      ds.points_rgb = std::move(random->rgb);
      std::copy(random->box_min, random->box_min + 3, ds.random_box_min);
      std::copy(random->box_max, random->box_max + 3, ds.random_box_max);
      ds.random_min_view_fraction = random->min_view_fraction;
    }
  }
  return ds;
}

// The views of the dataset at `root` (a folder or a transforms .json file) and the folder their
// names are relative to; `keep` (optional) receives a COLMAP layout's model as read.
struct Located {
  Source src;
  std::string folder;
};
Expected<Located> locate(const std::string& root, const DatasetOptions& options, ColmapModel* keep) {
  if (options.max_width < 0) return invalid_argument("load_dataset: max_width must be >= 0");
  if (options.llffhold < 0) return invalid_argument("load_dataset: llffhold must be >= 0");
  if (options.random_points < 0) return invalid_argument("load_dataset: random_points must be >= 0");
  if (!(options.fisheye_fov_deg == 0 || (options.fisheye_fov_deg >= 1 && options.fisheye_fov_deg <= 170)))
    return invalid_argument("load_dataset: the fisheye field of view must be 0 (automatic) or 1-170 degrees, got " +
                            std::to_string(options.fisheye_fov_deg));

  // A .json file: that transforms file (a NeRF synthetic split file: the pair beside it).
  if (ends_with(root, ".json") && platform::file_exists(root) && !platform::is_directory(root)) {
    const std::filesystem::path p(root);
    const std::string folder = p.has_parent_path() ? p.parent_path().string() : std::string(".");
    const std::string base = p.filename().string();
    std::vector<TransformsInput> inputs = {{root, ViewSpec::Split::kByName}};
    if (base == "transforms_train.json" || base == "transforms_test.json" || base == "transforms_val.json") {
      inputs = transforms_inputs(folder);
      if (inputs.empty()) return io_error(detail::join_path(folder, "transforms_train.json") + ": not found (beside " + root + ")");
    }
    auto src = transforms_source(folder, inputs, options);
    if (!src.ok()) return src.status();
    return Located{std::move(src).value(), folder};
  }

  const bool colmap_here = platform::is_directory(detail::join_path(root, options.sparse_dir));
  const std::vector<TransformsInput> inputs = transforms_inputs(root);
  DatasetLayout layout = options.layout;
  if (layout == DatasetLayout::kAuto) layout = (colmap_here || inputs.empty()) ? DatasetLayout::kColmap : DatasetLayout::kTransforms;
  if (layout == DatasetLayout::kTransforms) {
    if (inputs.empty())
      return io_error(root + ": no transforms.json or transforms_train.json (a NeRF-style dataset was asked for)");
    auto src = transforms_source(root, inputs, options);
    if (!src.ok()) return src.status();
    return Located{std::move(src).value(), root};
  }
  auto src = colmap_source(root, options, keep);
  if (!src.ok()) return src.status();
  return Located{std::move(src).value(), root};
}

Expected<Dataset> load(const std::string& root, const DatasetOptions& options) {
  auto located = locate(root, options, nullptr);
  if (!located.ok()) return located.status();
  return assemble(root, located->folder, std::move(located->src), options);
}

// A camera plan's stored camera (DatasetFileView::camera) with the given id.
ColmapCamera plan_camera(const CameraPlan& plan, uint32_t id) {
  ColmapCamera cam = plan.stored;
  cam.id = id;
  return cam;
}

Expected<DatasetFiles> files(const std::string& root, const DatasetOptions& options) {
  DatasetFiles out;
  auto located = locate(root, options, &out.model);
  if (!located.ok()) return located.status();
  Source& src = located->src;
  sort_views(&src);
  out.layout = src.layout;
  std::map<std::string, size_t> image_of_name;  // COLMAP: index in the model as read
  if (src.layout == DatasetLayout::kColmap) {
    for (size_t i = 0; i < out.model.images.size(); ++i) image_of_name[out.model.images[i].name] = i;
  } else {
    for (size_t p = 0; p < src.plans.size(); ++p) out.model.cameras.push_back(plan_camera(src.plans[p], uint32_t(p + 1)));
  }
  const std::string masks_root = searched_masks_folder(src, located->folder, options);
  for (size_t i = 0; i < src.views.size(); ++i) {
    const ViewSpec& spec = src.views[i];
    DatasetFileView v;
    v.name = spec.name;
    v.image_path = spec.image_path;
    std::string tried;
    v.mask_path = view_mask_file(spec, masks_root, &tried);
    v.is_test = is_test_view(spec, i, options);
    if (src.layout == DatasetLayout::kColmap) {
      v.model_image = image_of_name.at(spec.name);  // the views are the model's images
      v.camera = plan_camera(src.plans.at(spec.plan), out.model.images[v.model_image].camera_id);
    } else {
      ColmapImage im;
      im.id = spec.image_id;
      im.camera_id = uint32_t(spec.plan + 1);
      im.name = spec.name;
      std::copy(spec.qvec, spec.qvec + 4, im.qvec);
      std::copy(spec.tvec, spec.tvec + 3, im.tvec);
      v.model_image = out.model.images.size();
      out.model.images.push_back(std::move(im));
      v.camera = out.model.cameras.at(spec.plan);
    }
    out.views.push_back(std::move(v));
  }
  return out;
}

}  // namespace

const char* points_source_name(PointsSource source) {
  switch (source) {
    case PointsSource::kNone: return "none";
    case PointsSource::kSfm: return "sfm";
    case PointsSource::kPly: return "ply";
    case PointsSource::kRandom: return "random";
    case PointsSource::kCarved: return "carved";
  }
  return "?";
}

Expected<Dataset> load_dataset(const std::string& root, const DatasetOptions& options) {
  return detail::guarded(root, [&]() { return load(root, options); });
}

Expected<DatasetFiles> read_dataset_files(const std::string& root, const DatasetOptions& options) {
  return detail::guarded(root, [&]() { return files(root, options); });
}

}  // namespace gs::io
