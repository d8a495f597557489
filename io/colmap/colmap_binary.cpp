// SPDX-License-Identifier: MIT
// COLMAP binary format (cameras.bin, images.bin, points3D.bin; little-endian, packed). Every count
// read from the file is checked against the bytes that remain before anything is reserved, so a
// corrupt header cannot make us allocate gigabytes; errors name the record index and byte offset.
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <unordered_set>

#include "../io_util.h"
#include "colmap_internal.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

// Minimum bytes per record, used to bound header counts: cameras.bin id + model + w + h + 3 params;
// images.bin id + q + t + camera id + empty name's NUL + points count; points3D.bin fixed part.
constexpr size_t kMinCameraBytes = 4 + 4 + 8 + 8 + 3 * 8;
constexpr size_t kMinImageBytes = 4 + 4 * 8 + 3 * 8 + 4 + 1 + 8;
constexpr size_t kMinPointBytes = 8 + 3 * 8 + 3 + 8 + 8;
constexpr size_t kPoint2DBytes = 8 + 8 + 8;
constexpr size_t kTrackElementBytes = 4 + 4;
constexpr uint64_t kNoPoint3D = ~uint64_t(0);

// Sequential reader with a sticky failure: once a read runs past the end every later read
// returns 0, and status() describes the first failure with the record and byte offset.
class BinReader {
 public:
  BinReader(const uint8_t* data, size_t size, const std::string& source) : d_(data), n_(size), source_(source) {}

  void begin_record(uint64_t index) { record_ = int64_t(index), record_at_ = pos_; }
  size_t left() const { return n_ - pos_; }
  size_t pos() const { return pos_; }
  bool failed() const { return !error_.empty(); }
  Status status() const { return parse_error(error_); }

  Status error(const std::string& what) const { return parse_error(where() + what); }

  const uint8_t* take(size_t bytes, const char* field) {
    if (failed()) return nullptr;
    if (bytes > left()) {
      error_ = where() + "truncated: " + field + " needs " + std::to_string(bytes) + " bytes at byte offset " +
               std::to_string(pos_) + ", only " + std::to_string(left()) + " left";
      return nullptr;
    }
    const uint8_t* p = d_ + pos_;
    pos_ += bytes;
    return p;
  }
  uint8_t u8(const char* f) { const uint8_t* p = take(1, f); return p ? *p : 0; }
  uint32_t u32(const char* f) { const uint8_t* p = take(4, f); return p ? detail::load_u32(p) : 0; }
  uint64_t u64(const char* f) { const uint8_t* p = take(8, f); return p ? detail::load_u64(p) : 0; }
  double f64(const char* f) { const uint8_t* p = take(8, f); return p ? detail::load_f64(p) : 0.0; }

  // Header count, refused when even the smallest records would not fit in the bytes left.
  bool count(const char* what, size_t min_bytes_each, uint64_t* n) {
    *n = u64(what);
    if (failed()) return false;
    if (*n > left() / min_bytes_each) {
      error_ = where() + "claims " + std::to_string(*n) + " " + what + " (at least " + std::to_string(min_bytes_each) +
               " bytes each) but only " + std::to_string(left()) + " bytes remain: truncated or corrupt";
      return false;
    }
    return true;
  }

  std::string where() const {
    if (record_ < 0) return source_ + ": header: ";
    return source_ + ": record " + std::to_string(record_) + " at byte offset " + std::to_string(record_at_) + ": ";
  }

 private:
  const uint8_t* d_;
  size_t n_;
  size_t pos_ = 0;
  const std::string& source_;
  int64_t record_ = -1;
  size_t record_at_ = 0;
  std::string error_;
};

Status check_end(const BinReader& r, const std::string& source, uint64_t num, const char* what) {
  if (r.left() == 0) return Status::Ok();
  return parse_error(source + ": " + std::to_string(r.left()) + " bytes left after the " + std::to_string(num) + " " +
                     what + " the header announced (wrong count?)");
}

}  // namespace

Status parse_cameras_binary(const uint8_t* data, size_t size, const std::string& source, std::vector<ColmapCamera>* out) {
  return detail::guarded(source, [&]() -> Status {
    BinReader r(data, size, source);
    uint64_t num = 0;
    if (!r.count("cameras", kMinCameraBytes, &num)) return r.status();
    std::vector<ColmapCamera> cams;
    cams.reserve(size_t(num));
    std::unordered_set<uint32_t> ids;
    for (uint64_t i = 0; i < num; ++i) {
      r.begin_record(i);
      ColmapCamera cam;
      cam.id = r.u32("camera_id");
      const int32_t model_id = int32_t(r.u32("model_id"));
      const uint64_t w = r.u64("width"), h = r.u64("height");
      if (r.failed()) return r.status();
      const detail::CameraModelInfo* model = detail::find_camera_model(model_id);
      if (model == nullptr)
        return unsupported(r.where() + "unknown camera model id " + std::to_string(model_id) + " (camera " +
                           std::to_string(cam.id) + ")");
      if (w == 0 || w > uint64_t(detail::kMaxCameraSide) || h == 0 || h > uint64_t(detail::kMaxCameraSide))
        return r.error("camera size " + std::to_string(w) + "x" + std::to_string(h) + " outside 1.." +
                       std::to_string(detail::kMaxCameraSide));
      cam.model = model->name;
      cam.width = int(w), cam.height = int(h);
      cam.params.resize(size_t(model->num_params));
      for (double& p : cam.params) p = r.f64("params");
      if (r.failed()) return r.status();
      const std::string bad = detail::check_camera(cam);
      if (!bad.empty()) return r.error(bad + " (camera " + std::to_string(cam.id) + ")");
      if (!ids.insert(cam.id).second) return r.error("duplicate camera id " + std::to_string(cam.id));
      cams.push_back(std::move(cam));
    }
    GS_RETURN_IF_ERROR(check_end(r, source, num, "cameras"));
    *out = std::move(cams);
    return Status::Ok();
  });
}

Status parse_images_binary(const uint8_t* data, size_t size, const std::string& source, std::vector<ColmapImage>* out) {
  return detail::guarded(source, [&]() -> Status {
    BinReader r(data, size, source);
    uint64_t num = 0;
    if (!r.count("images", kMinImageBytes, &num)) return r.status();
    std::vector<ColmapImage> images;
    images.reserve(size_t(num));
    std::unordered_set<uint32_t> ids;
    for (uint64_t i = 0; i < num; ++i) {
      r.begin_record(i);
      ColmapImage im;
      im.id = r.u32("image_id");
      for (double& q : im.qvec) q = r.f64("qvec");
      for (double& t : im.tvec) t = r.f64("tvec");
      im.camera_id = r.u32("camera_id");
      if (r.failed()) return r.status();
      const uint8_t* name = data + r.pos();
      const void* nul = std::memchr(name, 0, r.left());
      if (nul == nullptr) {
        r.take(r.left() + 1, "name (no terminating NUL)");
        return r.status();
      }
      const size_t name_len = size_t(static_cast<const uint8_t*>(nul) - name);
      if (name_len == 0) return r.error("empty image name (image " + std::to_string(im.id) + ")");
      im.name.assign(reinterpret_cast<const char*>(name), name_len);
      r.take(name_len + 1, "name");
      const std::string bad = detail::check_pose(im.qvec, im.tvec);
      if (!bad.empty()) return r.error(bad + " (image " + std::to_string(im.id) + ")");
      if (!ids.insert(im.id).second) return r.error("duplicate image id " + std::to_string(im.id));

      uint64_t n2d = 0;
      if (!r.count("points2D", kPoint2DBytes, &n2d)) return r.status();
      im.points2d.resize(size_t(n2d));
      for (ColmapPoint2D& p : im.points2d) {
        p.xy[0] = r.f64("x");
        p.xy[1] = r.f64("y");
        const uint64_t id = r.u64("point3D_id");
        if (id != kNoPoint3D && id > uint64_t(INT64_MAX))
          return r.error("bad point3D_id " + std::to_string(id) + " (image " + std::to_string(im.id) + ")");
        p.point3d_id = id == kNoPoint3D ? -1 : int64_t(id);
      }
      if (r.failed()) return r.status();
      images.push_back(std::move(im));
    }
    GS_RETURN_IF_ERROR(check_end(r, source, num, "images"));
    *out = std::move(images);
    return Status::Ok();
  });
}

Status parse_points3d_binary(const uint8_t* data, size_t size, const std::string& source, std::vector<ColmapPoint3D>* out) {
  return detail::guarded(source, [&]() -> Status {
    BinReader r(data, size, source);
    uint64_t num = 0;
    if (!r.count("points", kMinPointBytes, &num)) return r.status();
    std::vector<ColmapPoint3D> points;
    points.reserve(size_t(num));
    std::unordered_set<uint64_t> ids;
    for (uint64_t i = 0; i < num; ++i) {
      r.begin_record(i);
      ColmapPoint3D p;
      p.id = r.u64("point3D_id");
      for (double& v : p.xyz) v = r.f64("xyz");
      for (uint8_t& c : p.rgb) c = r.u8("rgb");
      p.error = r.f64("error");
      if (r.failed()) return r.status();
      for (double v : p.xyz)
        if (!std::isfinite(v)) return r.error("point " + std::to_string(p.id) + " has a non-finite coordinate");
      if (!ids.insert(p.id).second) return r.error("duplicate point id " + std::to_string(p.id));
      uint64_t len = 0;
      if (!r.count("track elements", kTrackElementBytes, &len)) return r.status();
      p.track.resize(size_t(len));
      for (ColmapTrackElement& t : p.track) {
        t.image_id = r.u32("image_id");
        t.point2d_idx = r.u32("point2D_idx");
      }
      if (r.failed()) return r.status();
      points.push_back(std::move(p));
    }
    GS_RETURN_IF_ERROR(check_end(r, source, num, "points"));
    *out = std::move(points);
    return Status::Ok();
  });
}

Status write_colmap_binary(const ColmapModel& model, const std::string& dir) {
  return detail::guarded(dir, [&]() -> Status {
    std::vector<uint8_t> b;
    detail::append_u64(b, model.cameras.size());
    for (const ColmapCamera& c : model.cameras) {
      const std::string bad = detail::check_camera(c);
      if (!bad.empty()) return invalid_argument(dir + ": camera " + std::to_string(c.id) + ": " + bad);
      detail::append_u32(b, c.id);
      detail::append_u32(b, uint32_t(detail::find_camera_model(c.model)->id));
      detail::append_u64(b, uint64_t(c.width));
      detail::append_u64(b, uint64_t(c.height));
      for (double p : c.params) detail::append_f64(b, p);
    }
    std::vector<uint8_t> bi;
    detail::append_u64(bi, model.images.size());
    for (const ColmapImage& im : model.images) {
      if (im.name.empty() || im.name.find('\0') != std::string::npos)
        return invalid_argument(dir + ": image " + std::to_string(im.id) + " has an empty name or one with a NUL");
      detail::append_u32(bi, im.id);
      for (double q : im.qvec) detail::append_f64(bi, q);
      for (double t : im.tvec) detail::append_f64(bi, t);
      detail::append_u32(bi, im.camera_id);
      bi.insert(bi.end(), im.name.begin(), im.name.end());
      bi.push_back(0);
      detail::append_u64(bi, im.points2d.size());
      for (const ColmapPoint2D& p : im.points2d) {
        detail::append_f64(bi, p.xy[0]);
        detail::append_f64(bi, p.xy[1]);
        detail::append_u64(bi, p.point3d_id < 0 ? kNoPoint3D : uint64_t(p.point3d_id));
      }
    }
    std::vector<uint8_t> bp;
    detail::append_u64(bp, model.points.size());
    for (const ColmapPoint3D& p : model.points) {
      detail::append_u64(bp, p.id);
      for (double v : p.xyz) detail::append_f64(bp, v);
      for (uint8_t c : p.rgb) bp.push_back(c);
      detail::append_f64(bp, p.error);
      detail::append_u64(bp, p.track.size());
      for (const ColmapTrackElement& t : p.track) {
        detail::append_u32(bp, t.image_id);
        detail::append_u32(bp, t.point2d_idx);
      }
    }
    GS_RETURN_IF_ERROR(platform::make_dirs(dir));
    GS_RETURN_IF_ERROR(platform::write_file_atomic(detail::join_path(dir, "cameras.bin"), b.data(), b.size()));
    GS_RETURN_IF_ERROR(platform::write_file_atomic(detail::join_path(dir, "images.bin"), bi.data(), bi.size()));
    return platform::write_file_atomic(detail::join_path(dir, "points3D.bin"), bp.data(), bp.size());
  });
}

}  // namespace gs::io
