// SPDX-License-Identifier: MIT
// COLMAP text format (cameras.txt, images.txt, points3D.txt): line-based parsers that report
// "<file>: line N: <problem>", and writers that print doubles in shortest round-trip form.
#include <charconv>
#include <cmath>
#include <string_view>
#include <type_traits>
#include <unordered_set>

#include "../io_util.h"
#include "colmap_internal.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

using Tokens = std::vector<std::string_view>;

// Walks a text buffer line by line ('\n' or "\r\n"), counting lines from 1.
class LineReader {
 public:
  explicit LineReader(const std::string& text) : text_(text) {}
  bool next(std::string_view* line) {
    if (pos_ >= text_.size()) return false;
    size_t end = text_.find('\n', pos_);
    if (end == std::string::npos) end = text_.size();
    *line = std::string_view(text_).substr(pos_, end - pos_);
    if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
    pos_ = end + 1;
    ++line_no_;
    return true;
  }
  // Next line that is neither blank nor a '#' comment.
  bool next_data(std::string_view* line) {
    while (next(line)) {
      const size_t first = line->find_first_not_of(" \t");
      if (first != std::string_view::npos && (*line)[first] != '#') return true;
    }
    return false;
  }
  size_t line_no() const { return line_no_; }

 private:
  const std::string& text_;
  size_t pos_ = 0;
  size_t line_no_ = 0;
};

Tokens split(std::string_view line) {
  Tokens out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

template <class T>
bool parse_num(std::string_view tok, T* out) {
  const char* end = tok.data() + tok.size();
  auto r = std::from_chars(tok.data(), end, *out);
  return r.ec == std::errc() && r.ptr == end;
}

class TextErrors {
 public:
  TextErrors(const std::string& source, const LineReader& lines) : source_(source), lines_(lines) {}
  Status error(const std::string& what) const {
    return parse_error(source_ + ": line " + std::to_string(lines_.line_no()) + ": " + what);
  }
  template <class T>
  Status number(std::string_view tok, const char* field, T* out) const {
    if (parse_num(tok, out)) return Status::Ok();
    return error(std::string("bad ") + field + " '" + std::string(tok) + "' (not a valid " +
                 (std::is_floating_point<T>::value ? "number" : "integer for this field") + ")");
  }

 private:
  const std::string& source_;
  const LineReader& lines_;
};

void put(std::string& s, double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof(buf), v);
  s.append(buf, r.ptr);
}
template <class T>
void put_int(std::string& s, T v) {
  char buf[24];
  auto r = std::to_chars(buf, buf + sizeof(buf), v);
  s.append(buf, r.ptr);
}

}  // namespace

Status parse_cameras_text(const std::string& text, const std::string& source, std::vector<ColmapCamera>* out) {
  return detail::guarded(source, [&]() -> Status {
    LineReader lines(text);
    TextErrors err(source, lines);
    std::vector<ColmapCamera> cams;
    std::unordered_set<uint32_t> ids;
    std::string_view line;
    while (lines.next_data(&line)) {
      const Tokens t = split(line);
      if (t.size() < 4) return err.error("expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[], got " + std::to_string(t.size()) + " fields");
      ColmapCamera cam;
      int64_t w = 0, h = 0;
      GS_RETURN_IF_ERROR(err.number(t[0], "CAMERA_ID", &cam.id));
      cam.model = std::string(t[1]);
      GS_RETURN_IF_ERROR(err.number(t[2], "WIDTH", &w));
      GS_RETURN_IF_ERROR(err.number(t[3], "HEIGHT", &h));
      if (detail::find_camera_model(cam.model) == nullptr)
        return unsupported(source + ": line " + std::to_string(lines.line_no()) + ": unknown camera model '" + cam.model +
                           "' (camera " + std::to_string(cam.id) + ")");
      if (w <= 0 || w > detail::kMaxCameraSide || h <= 0 || h > detail::kMaxCameraSide)
        return err.error("camera size " + std::to_string(w) + "x" + std::to_string(h) + " outside 1.." +
                         std::to_string(detail::kMaxCameraSide));
      cam.width = int(w), cam.height = int(h);
      for (size_t i = 4; i < t.size(); ++i) {
        double p = 0;
        GS_RETURN_IF_ERROR(err.number(t[i], "PARAMS", &p));
        cam.params.push_back(p);
      }
      const std::string bad = detail::check_camera(cam);
      if (!bad.empty()) return err.error(bad + " (camera " + std::to_string(cam.id) + ")");
      if (!ids.insert(cam.id).second) return err.error("duplicate camera id " + std::to_string(cam.id));
      cams.push_back(std::move(cam));
    }
    *out = std::move(cams);
    return Status::Ok();
  });
}

Status parse_images_text(const std::string& text, const std::string& source, std::vector<ColmapImage>* out) {
  return detail::guarded(source, [&]() -> Status {
    LineReader lines(text);
    TextErrors err(source, lines);
    std::vector<ColmapImage> images;
    std::unordered_set<uint32_t> ids;
    std::string_view line;
    static const char* kPoseFields[7] = {"QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
    while (lines.next_data(&line)) {
      const Tokens t = split(line);
      if (t.size() < 10)
        return err.error("expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, got " + std::to_string(t.size()) + " fields");
      ColmapImage im;
      GS_RETURN_IF_ERROR(err.number(t[0], "IMAGE_ID", &im.id));
      for (int i = 0; i < 7; ++i)
        GS_RETURN_IF_ERROR(err.number(t[size_t(1 + i)], kPoseFields[i], i < 4 ? &im.qvec[i] : &im.tvec[i - 4]));
      GS_RETURN_IF_ERROR(err.number(t[8], "CAMERA_ID", &im.camera_id));
      // NAME is the rest of the line, so names with spaces survive a round trip.
      const size_t name_at = size_t(t[9].data() - line.data());
      std::string_view name = line.substr(name_at);
      name = name.substr(0, name.find_last_not_of(" \t") + 1);
      im.name = std::string(name);
      const std::string bad = detail::check_pose(im.qvec, im.tvec);
      if (!bad.empty()) return err.error(bad + " (image " + std::to_string(im.id) + ")");
      if (!ids.insert(im.id).second) return err.error("duplicate image id " + std::to_string(im.id));

      // The POINTS2D line follows directly; it may be blank, or missing at the end of the file.
      if (lines.next(&line)) {
        const Tokens p = split(line);
        if (p.size() % 3 != 0)
          return err.error("POINTS2D has " + std::to_string(p.size()) + " fields, not a multiple of 3 (X Y POINT3D_ID)");
        im.points2d.resize(p.size() / 3);
        for (size_t k = 0; k < im.points2d.size(); ++k) {
          ColmapPoint2D& pt = im.points2d[k];
          GS_RETURN_IF_ERROR(err.number(p[3 * k], "X", &pt.xy[0]));
          GS_RETURN_IF_ERROR(err.number(p[3 * k + 1], "Y", &pt.xy[1]));
          GS_RETURN_IF_ERROR(err.number(p[3 * k + 2], "POINT3D_ID", &pt.point3d_id));
          if (pt.point3d_id < -1) return err.error("bad POINT3D_ID " + std::to_string(pt.point3d_id));
        }
      }
      images.push_back(std::move(im));
    }
    *out = std::move(images);
    return Status::Ok();
  });
}

Status parse_points3d_text(const std::string& text, const std::string& source, std::vector<ColmapPoint3D>* out) {
  return detail::guarded(source, [&]() -> Status {
    LineReader lines(text);
    TextErrors err(source, lines);
    std::vector<ColmapPoint3D> points;
    std::unordered_set<uint64_t> ids;
    std::string_view line;
    static const char* kXyz[3] = {"X", "Y", "Z"};
    static const char* kRgb[3] = {"R", "G", "B"};
    while (lines.next_data(&line)) {
      const Tokens t = split(line);
      if (t.size() < 8 || (t.size() - 8) % 2 != 0)
        return err.error("expected POINT3D_ID X Y Z R G B ERROR TRACK[] (pairs), got " + std::to_string(t.size()) + " fields");
      ColmapPoint3D p;
      GS_RETURN_IF_ERROR(err.number(t[0], "POINT3D_ID", &p.id));
      for (int i = 0; i < 3; ++i) {
        GS_RETURN_IF_ERROR(err.number(t[size_t(1 + i)], kXyz[i], &p.xyz[i]));
        if (!std::isfinite(p.xyz[i])) return err.error(std::string(kXyz[i]) + " is not finite");
      }
      for (int i = 0; i < 3; ++i) {
        int v = 0;
        GS_RETURN_IF_ERROR(err.number(t[size_t(4 + i)], kRgb[i], &v));
        if (v < 0 || v > 255) return err.error(std::string(kRgb[i]) + " " + std::to_string(v) + " outside 0..255");
        p.rgb[i] = uint8_t(v);
      }
      GS_RETURN_IF_ERROR(err.number(t[7], "ERROR", &p.error));
      p.track.resize((t.size() - 8) / 2);
      for (size_t k = 0; k < p.track.size(); ++k) {
        GS_RETURN_IF_ERROR(err.number(t[8 + 2 * k], "IMAGE_ID", &p.track[k].image_id));
        GS_RETURN_IF_ERROR(err.number(t[9 + 2 * k], "POINT2D_IDX", &p.track[k].point2d_idx));
      }
      if (!ids.insert(p.id).second) return err.error("duplicate point id " + std::to_string(p.id));
      points.push_back(std::move(p));
    }
    *out = std::move(points);
    return Status::Ok();
  });
}

Status write_colmap_text(const ColmapModel& model, const std::string& dir) {
  return detail::guarded(dir, [&]() -> Status {
    for (const ColmapCamera& c : model.cameras) {
      const std::string bad = detail::check_camera(c);
      if (!bad.empty()) return invalid_argument(dir + ": camera " + std::to_string(c.id) + ": " + bad);
    }
    for (const ColmapImage& im : model.images)
      if (im.name.empty() || im.name.find_first_of("\r\n") != std::string::npos)
        return invalid_argument(dir + ": image " + std::to_string(im.id) + " has an empty or multi-line name");
    GS_RETURN_IF_ERROR(platform::make_dirs(dir));

    std::string s = "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n";
    s += "# Number of cameras: " + std::to_string(model.cameras.size()) + "\n";
    for (const ColmapCamera& c : model.cameras) {
      s += std::to_string(c.id) + " " + c.model + " " + std::to_string(c.width) + " " + std::to_string(c.height);
      for (double p : c.params) s += ' ', put(s, p);
      s += '\n';
    }
    GS_RETURN_IF_ERROR(platform::write_file_atomic(detail::join_path(dir, "cameras.txt"), s));

    s = "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
        "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
    s += "# Number of images: " + std::to_string(model.images.size()) + "\n";
    for (const ColmapImage& im : model.images) {
      s += std::to_string(im.id);
      for (double q : im.qvec) s += ' ', put(s, q);
      for (double v : im.tvec) s += ' ', put(s, v);
      s += ' ' + std::to_string(im.camera_id) + ' ' + im.name + '\n';
      for (size_t k = 0; k < im.points2d.size(); ++k) {
        if (k) s += ' ';
        put(s, im.points2d[k].xy[0]), s += ' ', put(s, im.points2d[k].xy[1]), s += ' ';
        put_int(s, im.points2d[k].point3d_id < 0 ? int64_t(-1) : im.points2d[k].point3d_id);
      }
      s += '\n';
    }
    GS_RETURN_IF_ERROR(platform::write_file_atomic(detail::join_path(dir, "images.txt"), s));

    s = "# 3D point list with one line of data per point:\n"
        "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n";
    s += "# Number of points: " + std::to_string(model.points.size()) + "\n";
    for (const ColmapPoint3D& p : model.points) {
      put_int(s, p.id);
      for (double v : p.xyz) s += ' ', put(s, v);
      for (uint8_t c : p.rgb) s += ' ' + std::to_string(int(c));
      s += ' ', put(s, p.error);
      for (const ColmapTrackElement& t : p.track) s += ' ' + std::to_string(t.image_id) + ' ' + std::to_string(t.point2d_idx);
      s += '\n';
    }
    return platform::write_file_atomic(detail::join_path(dir, "points3D.txt"), s);
  });
}

}  // namespace gs::io
