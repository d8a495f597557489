// SPDX-License-Identifier: MIT
// The transforms.json writer (nerfstudio's layout): the counterpart of parse_transforms_json, used
// for the object captures of hbgs synth and for the posed models hbgs train and hbgs register write
// beside their COLMAP text models. Everything it writes, hbgs's own parser reads back unchanged.
#include <nlohmann/json.hpp>

#include <cmath>

#include "../io_util.h"
#include "gs/io/image.h"
#include "gs/io/transforms.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

using Json = nlohmann::ordered_json;

// The optional fields of the intrinsics, for comparing and checking them in one loop.
constexpr std::optional<double> TransformsIntrinsics::*kDoubleFields[] = {
    &TransformsIntrinsics::fl_x, &TransformsIntrinsics::fl_y, &TransformsIntrinsics::cx,
    &TransformsIntrinsics::cy,   &TransformsIntrinsics::camera_angle_x, &TransformsIntrinsics::camera_angle_y,
    &TransformsIntrinsics::k1,   &TransformsIntrinsics::k2, &TransformsIntrinsics::k3,
    &TransformsIntrinsics::k4,   &TransformsIntrinsics::p1, &TransformsIntrinsics::p2};

bool same_intrinsics(const TransformsIntrinsics& a, const TransformsIntrinsics& b) {
  for (auto field : kDoubleFields)
    if (a.*field != b.*field) return false;
  return a.w == b.w && a.h == b.h;
}

bool distorted(const TransformsIntrinsics& in) {
  return in.k1.value_or(0) != 0 || in.k2.value_or(0) != 0 || in.p1.value_or(0) != 0 || in.p2.value_or(0) != 0;
}

// What the writer needs of a frame's intrinsics (see encode_transforms_json); "" when fine.
std::string intrinsics_problem(const TransformsIntrinsics& in) {
  const std::pair<const char*, std::optional<double>> required[] = {{"fl_x", in.fl_x}, {"fl_y", in.fl_y}, {"cx", in.cx}, {"cy", in.cy}};
  for (const auto& [name, value] : required)
    if (!value) return std::string("no '") + name + "' (the writer needs fl_x, fl_y, cx, cy, w and h)";
  if (!in.w || !in.h) return "no 'w' or 'h' (the writer needs fl_x, fl_y, cx, cy, w and h)";
  for (auto field : kDoubleFields)
    if (in.*field && !std::isfinite(*(in.*field))) return "an intrinsic is not finite";
  if (!(*in.fl_x > 0 && *in.fl_y > 0)) return "the focal lengths must be > 0";
  if (*in.w < 1 || *in.h < 1 || *in.w > kMaxImageSide || *in.h > kMaxImageSide)
    return "the image size " + std::to_string(*in.w) + "x" + std::to_string(*in.h) + " is outside 1.." + std::to_string(kMaxImageSide);
  if (in.k3.value_or(0) != 0 || in.k4.value_or(0) != 0) return "k3 and k4 must be 0 (hbgs reads k1, k2, p1, p2 only)";
  return "";
}

void put_intrinsics(const TransformsIntrinsics& in, bool opencv, Json* j) {
  if (in.camera_angle_x) (*j)["camera_angle_x"] = *in.camera_angle_x;
  if (in.camera_angle_y) (*j)["camera_angle_y"] = *in.camera_angle_y;
  (*j)["fl_x"] = *in.fl_x;
  (*j)["fl_y"] = *in.fl_y;
  (*j)["cx"] = *in.cx;
  (*j)["cy"] = *in.cy;
  (*j)["w"] = *in.w;
  (*j)["h"] = *in.h;
  if (!opencv) return;
  (*j)["k1"] = in.k1.value_or(0);
  (*j)["k2"] = in.k2.value_or(0);
  (*j)["p1"] = in.p1.value_or(0);
  (*j)["p2"] = in.p2.value_or(0);
}

Expected<std::string> encode(const TransformsFile& file, const std::string& source) {
  if (file.frames.empty()) return invalid_argument(source + ": no frames to write");
  bool shared = true, opencv = false;
  for (size_t i = 0; i < file.frames.size(); ++i) {
    const TransformsFrame& f = file.frames[i];
    const std::string at = source + ": frame " + std::to_string(i) + " (" + f.file_path + "): ";
    if (f.file_path.empty()) return invalid_argument(source + ": frame " + std::to_string(i) + ": empty file_path");
    if (std::string why = intrinsics_problem(f.intrinsics); !why.empty()) return invalid_argument(at + why);
    double q[4], t[3];
    if (std::string why = pose_from_transform_matrix(f.transform_matrix, q, t); !why.empty())
      return invalid_argument(at + "transform_matrix is not a camera pose: " + why);
    shared = shared && same_intrinsics(f.intrinsics, file.frames.front().intrinsics);
    opencv = opencv || distorted(f.intrinsics);
  }
  Json top;
  top["camera_model"] = opencv ? "OPENCV" : "PINHOLE";
  if (shared) put_intrinsics(file.frames.front().intrinsics, opencv, &top);
  Json frames = Json::array();
  for (const TransformsFrame& f : file.frames) {
    Json frame;
    frame["file_path"] = f.file_path;
    if (!f.mask_path.empty()) frame["mask_path"] = f.mask_path;
    if (!shared) put_intrinsics(f.intrinsics, opencv, &frame);
    Json rows = Json::array();
    for (int r = 0; r < 4; ++r) {
      const double* m = f.transform_matrix + 4 * r;
      rows.push_back({m[0], m[1], m[2], m[3]});
    }
    frame["transform_matrix"] = std::move(rows);
    frames.push_back(std::move(frame));
  }
  top["frames"] = std::move(frames);
  const std::pair<const char*, const std::optional<std::vector<std::string>>*> lists[] = {
      {"train_filenames", &file.train_filenames}, {"val_filenames", &file.val_filenames}, {"test_filenames", &file.test_filenames}};
  for (const auto& [key, list] : lists)
    if (*list) top[key] = **list;
  if (!file.ply_file_path.empty()) top["ply_file_path"] = file.ply_file_path;
  return top.dump(2) + "\n";
}

}  // namespace

Expected<std::string> encode_transforms_json(const TransformsFile& file, const std::string& source) {
  return detail::guarded(source, [&]() { return encode(file, source); });
}

Status write_transforms_json(const std::string& path, const TransformsFile& file) {
  Expected<std::string> text = encode_transforms_json(file, path);
  if (!text.ok()) return text.status();
  return platform::write_file_atomic(path, *text);
}

Expected<TransformsIntrinsics> transforms_intrinsics(const ColmapCamera& camera) {
  const std::vector<double>& p = camera.params;
  const std::string what = "camera " + std::to_string(camera.id) + " (" + camera.model + ")";
  TransformsIntrinsics in;
  if (camera.model == "PINHOLE" && p.size() == 4) {
    in.fl_x = p[0], in.fl_y = p[1], in.cx = p[2], in.cy = p[3];
  } else if (camera.model == "SIMPLE_PINHOLE" && p.size() == 3) {
    in.fl_x = in.fl_y = p[0], in.cx = p[1], in.cy = p[2];
  } else if (camera.model == "OPENCV" && p.size() == 8) {
    in.fl_x = p[0], in.fl_y = p[1], in.cx = p[2], in.cy = p[3];
    in.k1 = p[4], in.k2 = p[5], in.p1 = p[6], in.p2 = p[7];
  } else {
    return invalid_argument(what + " with " + std::to_string(p.size()) +
                            " parameters cannot be written to a transforms file (PINHOLE: 4, SIMPLE_PINHOLE: 3, OPENCV: 8)");
  }
  in.w = camera.width;
  in.h = camera.height;
  return in;
}

}  // namespace gs::io
