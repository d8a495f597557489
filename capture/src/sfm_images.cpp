// SPDX-License-Identifier: MIT
// Choice of the images for the SfM pose initialisation (see sfm_images.h).
#include "gs/capture/sfm_images.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

#include "gs/io/image.h"

namespace gs::capture {
namespace {

namespace fs = std::filesystem;

// The view's camera at width x height: intrinsics scaled per axis (COLMAP's pixel-centre
// convention makes a uniform resize scale cx, cy like fx, fy).
Camera scaled_to(const Camera& c, int width, int height) {
  Camera s = c;
  const double sx = double(width) / c.intr.width, sy = double(height) / c.intr.height;
  s.intr.fx = float(c.intr.fx * sx);
  s.intr.fy = float(c.intr.fy * sy);
  s.intr.cx = float(c.intr.cx * sx);
  s.intr.cy = float(c.intr.cy * sy);
  s.intr.width = width;
  s.intr.height = height;
  return s;
}

// Whether width x height is the view's size scaled uniformly, within a pixel of rounding.
bool same_aspect(const io::DatasetView& v, int width, int height) {
  const double s = double(width) / v.camera.intr.width;
  return std::abs(s * v.camera.intr.height - height) <= 1.0;
}

// Every view's image from folder, checked; the first problem as an error.
Expected<SfmImages> load_folder(const std::string& folder, const std::vector<const io::DatasetView*>& views) {
  SfmImages out;
  out.folder = folder;
  for (const io::DatasetView* v : views) {
    const std::string path = (fs::path(folder) / v->name).string();
    Expected<io::Image8> im = io::read_image(path, 3);
    if (!im.ok()) return im.status();
    if (!same_aspect(*v, im->width, im->height) || (!out.images.empty() && im->width != out.images[0].width))
      return invalid_argument(path + ": " + std::to_string(im->width) + "x" + std::to_string(im->height) +
                              " is not the training image's " + std::to_string(v->camera.intr.width) + "x" +
                              std::to_string(v->camera.intr.height) + " scaled uniformly like the other views");
    out.cameras.push_back(scaled_to(v->camera, im->width, im->height));
    out.images.push_back(std::move(im).value());
  }
  return out;
}

SfmImages as_loaded(const std::vector<const io::DatasetView*>& views) {
  SfmImages out;
  for (const io::DatasetView* v : views) out.cameras.push_back(v->camera);
  return out;
}

std::string explicit_folder(const std::string& dataset, const std::string& choice) {
  const fs::path inside = fs::path(dataset) / choice;
  std::error_code ec;
  return fs::is_directory(inside, ec) ? inside.string() : choice;
}

}  // namespace

Status check_sfm_images_choice(const std::string& dataset, const std::string& choice) {
  if (choice == "auto" || choice == "train") return Status::Ok();
  std::error_code ec;
  if (!fs::is_directory(explicit_folder(dataset, choice), ec))
    return invalid_argument("SfM images folder " + choice + " not found (in " + dataset + " or as a path)");
  return Status::Ok();
}

Expected<SfmImages> choose_sfm_images(const std::string& dataset, const std::string& choice,
                                      const std::vector<const io::DatasetView*>& views, int max_size) {
  if (views.empty()) return invalid_argument("no views to reconstruct");
  if (choice == "train") return as_loaded(views);
  if (choice != "auto") {
    GS_RETURN_IF_ERROR(check_sfm_images_choice(dataset, choice));
    return load_folder(explicit_folder(dataset, choice), views);
  }
  // auto: the widest images* folder whose first view is larger than loaded, within max_size.
  const io::DatasetView& first = *views.front();
  std::string best;
  int best_width = first.camera.intr.width;
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(dataset, ec)) {
    const std::string name = e.path().filename().string();
    if (!e.is_directory(ec) || name.rfind("images", 0) != 0) continue;
    Expected<io::Image8> im = io::read_image((e.path() / first.name).string(), 3);
    if (!im.ok() || std::max(im->width, im->height) > max_size || !same_aspect(first, im->width, im->height)) continue;
    if (im->width > best_width) best = e.path().string(), best_width = im->width;
  }
  if (best.empty()) return as_loaded(views);
  Expected<SfmImages> loaded = load_folder(best, views);
  if (loaded.ok()) return loaded;
  SfmImages fallback = as_loaded(views);
  fallback.note = best + " passed over: " + loaded.status().message();
  return fallback;
}

}  // namespace gs::capture
