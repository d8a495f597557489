// SPDX-License-Identifier: MIT
// The independent reader (issue 16, issue 22): PlayCanvas's splat-transform, 2.7.1 and 3.7.0 (npm),
// reads what hbgs writes, and hbgs reads what splat-transform writes. For each release:
//   1. installs both releases with one npm command into --npm-dir (as the aliases st-2.7.1 and
//      st-3.7.0; reused when there), or exits 77 (ctest: skipped) with the reason when node/npm are
//      missing or the registry is unreachable; a release that does not run on this node is skipped
//      with the reason, the other still runs;
//   2. writes a seeded cloud with hbgs as 3DGS PLY, .splat, .spz (version 4, the default, and 3)
//      and compressed.ply, has splat-transform convert each to CSV (its columns in PLY terms:
//      position, log scale, logit opacity, SH DC) and compares per-column statistics (count; means
//      of position, log scale, opacity, colour) with hbgs's own reading of the file and with the
//      cloud written, each within the format's quantisation; the splats are also compared one by
//      one (same order);
//   3. has splat-transform convert hbgs's PLY to .spz version 3 and version 4 (its default),
//      compressed.ply and, where it can (3.x; checked either way), .splat; reads them with hbgs,
//      matches the splats to the cloud written (compressed.ply and .splat by position), checks every
//      field within quantisation and the renders' PSNR, and the v4 render within 0.1 dB of v3's.
// Usage: splat_transform_interop --npm-dir DIR --work DIR
#include <stdio.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "gs/io/splat_formats.h"
#include "splat_test_util.h"

namespace {

namespace fs = std::filesystem;
using gs::GaussianCloud;
using gs::io::SplatFormat;

constexpr int kSkip = 77;  // ctest SKIP_RETURN_CODE
// The releases tested: 2.7.1 (the last 2.x) and 3.7.0 (current when written), and where they
// differ. 3.x asks for node 22 in package.json but runs on 20.
struct Release {
  const char* version;
  bool writes_splat;  // 2.x has no .splat writer
  // 2.x converts between PLY's frame (RDF: y down, z forward) and the .spz specification's RUB (y
  // up, z backward) like hbgs; 3.x stores and reads .spz "raw", the PLY frame as it is (its
  // spz-module: "no coordinate conversion"), so its .spz files and hbgs's are mirrored in y and z.
  bool spz_raw_frame;
};
constexpr Release kReleases[] = {{"2.7.1", false, false}, {"3.7.0", true, true}};
constexpr double kShC0 = 0.28209479177387814;

int failures = 0;

void fail(const char* fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  std::fprintf(stdout, "FAIL: ");
  std::vfprintf(stdout, fmt, ap);
  std::fprintf(stdout, "\n");
  va_end(ap);
  ++failures;
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Runs a shell command; returns its exit code and its output (stdout and stderr).
int run(const std::string& command, std::string* output) {
  output->clear();
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) output->append(buf, n);
  const int status = ::pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string tail(const std::string& s, size_t lines) {
  size_t at = s.size();
  for (size_t k = 0; k <= lines && at > 0; ++k) at = s.rfind('\n', at - 1);
  return at == std::string::npos ? s : s.substr(at + 1);
}

// The columns of a CSV splat-transform wrote (a header line of names, then numbers).
bool read_csv(const std::string& path, std::map<std::string, std::vector<double>>* columns, size_t* rows) {
  std::ifstream f(path);
  std::string line;
  if (!std::getline(f, line)) return false;
  std::vector<std::string> names;
  std::stringstream hs(line);
  for (std::string name; std::getline(hs, name, ',');) names.push_back(name);
  columns->clear();
  *rows = 0;
  while (std::getline(f, line)) {
    if (line.empty()) continue;
    const char* s = line.c_str();
    for (size_t c = 0; c < names.size(); ++c) {
      char* end = nullptr;
      (*columns)[names[c]].push_back(std::strtod(s, &end));  // also reads Infinity and NaN
      if (end == s) return false;
      s = *end == ',' ? end + 1 : end;
    }
    ++*rows;
  }
  return true;
}

// Means of the fields the issue names, in the units hbgs compares them in.
struct Stats {
  size_t count = 0;
  double position[3] = {0, 0, 0}, log_scale[3] = {0, 0, 0}, opacity = 0, colour[3] = {0, 0, 0};
};

Stats stats_of(const GaussianCloud& c) {
  Stats s;
  s.count = c.size();
  const size_t K = size_t(gs::sh_coeff_count(c.sh_degree));
  for (size_t i = 0; i < c.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      s.position[a] += c.means[3 * i + size_t(a)];
      s.log_scale[a] += c.log_scales[3 * i + size_t(a)];
      s.colour[a] += 0.5 + kShC0 * c.sh[i * K * 3 + size_t(a)];
    }
    s.opacity += gs::io::test::sigmoid(c.opacity_logits[i]);
  }
  const double n = double(std::max<size_t>(c.size(), 1));
  for (int a = 0; a < 3; ++a) s.position[a] /= n, s.log_scale[a] /= n, s.colour[a] /= n;
  s.opacity /= n;
  return s;
}

// splat-transform's columns as a cloud (SH degree 0: the comparisons use the DC terms only).
GaussianCloud cloud_of(const std::map<std::string, std::vector<double>>& col, size_t rows) {
  GaussianCloud c;
  c.sh_degree = 0;
  c.resize(rows);
  auto get = [&](const char* name, size_t i) { return float(col.at(name)[i]); };
  for (size_t i = 0; i < rows; ++i) {
    const char* pos[3] = {"x", "y", "z"};
    for (int a = 0; a < 3; ++a) {
      c.means[3 * i + size_t(a)] = get(pos[a], i);
      c.log_scales[3 * i + size_t(a)] = get(("scale_" + std::to_string(a)).c_str(), i);
      c.sh[3 * i + size_t(a)] = get(("f_dc_" + std::to_string(a)).c_str(), i);
    }
    for (int k = 0; k < 4; ++k) c.quats[4 * i + size_t(k)] = get(("rot_" + std::to_string(k)).c_str(), i);
    c.opacity_logits[i] = get("opacity", i);
  }
  return c;
}

void print_stats(const char* who, const Stats& s) {
  std::printf("  %-28s %6zu  pos %9.6f %9.6f %9.6f  log-scale %9.6f %9.6f %9.6f  opacity %8.6f  colour %8.6f %8.6f %8.6f\n",
              who, s.count, s.position[0], s.position[1], s.position[2], s.log_scale[0], s.log_scale[1], s.log_scale[2],
              s.opacity, s.colour[0], s.colour[1], s.colour[2]);
}

// Per-field bound on |a - b| (and so on the difference of their means).
struct Bounds {
  double position, log_scale, opacity, colour;
};

void compare_stats(const std::string& what, const Stats& a, const Stats& b, const Bounds& bound) {
  if (a.count != b.count) fail("%s: count %zu vs %zu", what.c_str(), a.count, b.count);
  for (int k = 0; k < 3; ++k) {
    if (std::fabs(a.position[k] - b.position[k]) > bound.position)
      fail("%s: mean position %d differs by %g (bound %g)", what.c_str(), k, std::fabs(a.position[k] - b.position[k]), bound.position);
    if (std::fabs(a.log_scale[k] - b.log_scale[k]) > bound.log_scale)
      fail("%s: mean log scale %d differs by %g (bound %g)", what.c_str(), k, std::fabs(a.log_scale[k] - b.log_scale[k]), bound.log_scale);
    if (std::fabs(a.colour[k] - b.colour[k]) > bound.colour)
      fail("%s: mean colour %d differs by %g (bound %g)", what.c_str(), k, std::fabs(a.colour[k] - b.colour[k]), bound.colour);
  }
  if (std::fabs(a.opacity - b.opacity) > bound.opacity)
    fail("%s: mean opacity differs by %g (bound %g)", what.c_str(), std::fabs(a.opacity - b.opacity), bound.opacity);
}

// Largest per-splat differences of b's splat j from a's splat match[j].
struct FieldErrors {
  double position = 0, log_scale = 0, opacity = 0, colour = 0, rotation_deg = 0, sh1 = 0, sh_rest = 0;
};

FieldErrors field_errors(const GaussianCloud& a, const GaussianCloud& b, const std::vector<size_t>& match) {
  FieldErrors e;
  const size_t Ka = size_t(gs::sh_coeff_count(a.sh_degree)), Kb = size_t(gs::sh_coeff_count(b.sh_degree));
  for (size_t j = 0; j < b.size(); ++j) {
    const size_t i = match[j];
    for (size_t c = 0; c < 3; ++c) {
      e.position = std::max(e.position, std::fabs(double(a.means[3 * i + c]) - b.means[3 * j + c]));
      e.log_scale = std::max(e.log_scale, std::fabs(double(a.log_scales[3 * i + c]) - b.log_scales[3 * j + c]));
      e.colour = std::max(e.colour, kShC0 * std::fabs(double(a.sh[i * Ka * 3 + c]) - b.sh[j * Kb * 3 + c]));
    }
    e.opacity = std::max(e.opacity, std::fabs(gs::io::test::sigmoid(a.opacity_logits[i]) -
                                              gs::io::test::sigmoid(b.opacity_logits[j])));
    e.rotation_deg = std::max(e.rotation_deg, gs::io::test::rotation_angle_deg(&a.quats[4 * i], &b.quats[4 * j]));
    for (size_t k = 1; k < std::min(Ka, Kb); ++k)
      for (size_t c = 0; c < 3; ++c) {
        double& slot = k < 4 ? e.sh1 : e.sh_rest;
        slot = std::max(slot, std::fabs(double(a.sh[(i * Ka + k) * 3 + c]) - b.sh[(j * Kb + k) * 3 + c]));
      }
  }
  return e;
}

void print_errors(const std::string& what, const FieldErrors& e) {
  std::printf("  %-40s max |error|: position %.3g, log scale %.3g, opacity %.3g, colour %.3g, rotation %.3g deg, "
              "SH1 %.3g, SH2-3 %.3g\n",
              what.c_str(), e.position, e.log_scale, e.opacity, e.colour, e.rotation_deg, e.sh1, e.sh_rest);
}

// For every splat of b, the splat of a nearest in position (brute force: a few thousand splats).
std::vector<size_t> nearest_match(const GaussianCloud& a, const GaussianCloud& b) {
  std::vector<size_t> match(b.size());
  for (size_t j = 0; j < b.size(); ++j) {
    double best = 1e300;
    for (size_t i = 0; i < a.size(); ++i) {
      double d = 0;
      for (size_t c = 0; c < 3; ++c) {
        const double t = double(a.means[3 * i + c]) - b.means[3 * j + c];
        d += t * t;
      }
      if (d < best) best = d, match[j] = i;
    }
  }
  return match;
}

std::vector<size_t> identity(size_t n) {
  std::vector<size_t> v(n);
  for (size_t i = 0; i < n; ++i) v[i] = i;
  return v;
}

// The cloud under the frame change (x, y, z) -> (x, -y, -z) (a half turn about x): positions and
// the quaternion's y and z negated; each SH coefficient Y_l^m picks up (-1)^(l + |m|) from its
// associated Legendre factor (z -> -z is theta -> pi - theta) and -1 more for m < 0 (sin(m phi),
// y -> -y is phi -> -phi). Derived here, not taken from hbgs's .spz code it checks.
GaussianCloud mirrored_yz(const GaussianCloud& c) {
  GaussianCloud m = c;
  const size_t K = size_t(gs::sh_coeff_count(c.sh_degree));
  for (size_t i = 0; i < c.size(); ++i) {
    m.means[3 * i + 1] = -c.means[3 * i + 1];
    m.means[3 * i + 2] = -c.means[3 * i + 2];
    m.quats[4 * i + 2] = -c.quats[4 * i + 2];
    m.quats[4 * i + 3] = -c.quats[4 * i + 3];
    for (size_t k = 1; k < K; ++k) {
      const int l = int(std::sqrt(double(k)) + 1e-9), order = int(k) - l * l - l;
      const int sign = ((l + std::abs(order)) % 2 ? -1 : 1) * (order < 0 ? -1 : 1);
      for (size_t ch = 0; ch < 3; ++ch) m.sh[(i * K + k) * 3 + ch] *= float(sign);
    }
  }
  return m;
}

// The package directory of a release installed under its alias.
std::string package_dir_of(const std::string& npm_dir, const Release& r) {
  return npm_dir + "/node_modules/st-" + r.version;
}

bool installed(const std::string& npm_dir, const Release& r) {
  std::ifstream pj(package_dir_of(npm_dir, r) + "/package.json");
  std::stringstream ss;
  ss << pj.rdbuf();
  return ss.str().find(std::string("\"version\": \"") + r.version + "\"") != std::string::npos;
}

// The first bytes of a file.
std::string file_head(const std::string& path, size_t n) {
  std::ifstream f(path, std::ios::binary);
  std::string head(n, '\0');
  f.read(&head[0], long(n));
  head.resize(size_t(f.gcount()));
  return head;
}

// Sections 2 and 3 for one release; `cli` runs it.
struct Scene {
  GaussianCloud cloud;
  Stats truth;
  gs::Camera cam;
  std::vector<float> reference_render, reference_render_dc;
};

void check_release(const Release& release, const std::string& cli, const std::string& work, const Scene& scene) {
  std::string out;
  auto splat_transform = [&](const std::string& args, std::string* output) {
    return run("node " + quote(cli) + " -q -w " + args, output);
  };
  const GaussianCloud& cloud = scene.cloud;
  const std::string tag = std::string("[") + release.version + "] ";
  fs::create_directories(work);

  // 2. hbgs writes, splat-transform reads. Bounds on the difference of means from the cloud
  // written: the format's per-splat bound (README "Splat file formats"); between the two readers
  // of the same file: float32 rounding, 1e-5.
  struct Written {
    const char* file;
    Bounds from_truth;
    int spz_version;  // for .spz
  };
  const double spz_colour = 0.5 / 255 * kShC0 / 0.15;
  const Bounds spz_bounds{std::ldexp(1.0, -21), 1.0 / 32, 0.5 / 255, spz_colour};
  const Written written[] = {
      {"hbgs.ply", {1e-6, 1e-6, 1e-6, 1e-6}, 0},
      {"hbgs.splat", {1e-6, 1e-6, 0.5 / 255, 0.5 / 255}, 0},
      {"hbgs.spz", spz_bounds, 4},
      {"hbgs_v3.spz", spz_bounds, 3},
      // compressed.ply: half a step of a chunk's range; this cloud's chunks span under 2.9 units
      // (position, 11/10 bits), 2.3 in log scale and 1 in colour (8 bits).
      {"hbgs.compressed.ply", {2.9 / 1023 / 2, 2.3 / 1023 / 2, 0.5 / 255, 0.5 / 255}, 0},
  };
  const Bounds same_file{1e-5, 1e-5, 1e-5, 1e-5};
  std::printf("\n%s[hbgs writes, splat-transform reads] means (colour = 0.5 + SH_C0 dc, opacity = sigmoid):\n", tag.c_str());
  print_stats("written cloud", scene.truth);
  for (const Written& w : written) {
    const std::string path = work + "/" + w.file;
    gs::io::SplatWriteOptions options;
    if (w.spz_version) options.spz.version = w.spz_version;
    if (gs::Status st = gs::io::write_gaussians(path, cloud, options); !st.ok()) {
      fail("%s%s: %s", tag.c_str(), w.file, st.to_string().c_str());
      continue;
    }
    if (w.spz_version == 4 && file_head(path, 5) != std::string("NGSP\x04", 5))
      fail("%s%s: not a version-4 .spz (no plain NGSP header, version 4)", tag.c_str(), w.file);
    gs::Expected<GaussianCloud> ours = gs::io::read_gaussians(path);
    if (!ours.ok()) {
      fail("%shbgs cannot read its own %s: %s", tag.c_str(), w.file, ours.status().to_string().c_str());
      continue;
    }
    const std::string csv = path + ".csv";
    if (splat_transform(quote(path) + " " + quote(csv), &out) != 0) {
      fail("%ssplat-transform cannot read %s:\n%s", tag.c_str(), w.file, tail(out, 10).c_str());
      continue;
    }
    std::map<std::string, std::vector<double>> columns;
    size_t rows = 0;
    if (!read_csv(csv, &columns, &rows) || !columns.count("x") || !columns.count("rot_3")) {
      fail("%s%s: unreadable CSV from splat-transform", tag.c_str(), w.file);
      continue;
    }
    const GaussianCloud theirs = cloud_of(columns, rows);
    // A raw-frame release reads hbgs's .spz (RUB, as specified) mirrored: compared in its frame.
    const bool mirrored = release.spz_raw_frame && w.spz_version > 0;
    if (mirrored) *ours = mirrored_yz(*ours);
    const Stats st = stats_of(theirs), own = stats_of(*ours);
    std::printf("  %s (%.2f bytes per splat):\n", w.file, double(fs::file_size(path)) / double(cloud.size()));
    print_stats("  read by splat-transform", st);
    print_stats(mirrored ? "  read by hbgs, y z negated" : "  read by hbgs", own);
    compare_stats(tag + w.file + ": splat-transform vs the cloud written", st, mirrored ? stats_of(mirrored_yz(cloud)) : scene.truth,
                  w.from_truth);
    compare_stats(tag + w.file + ": splat-transform vs hbgs reading it", st, own, same_file);
    // Splat by splat (both readers keep the file's order): identical to float rounding, except
    // the .splat rotation: splat-transform decodes its bytes as b / 127.5 - 1, hbgs as
    // (b - 128) / 128 like antimatter15's viewer (the inverse of its q * 128 + 128): half a step
    // on all four components, up to 2 asin(sqrt(4) / 256) = 0.9 degrees apart.
    const FieldErrors e = field_errors(*ours, theirs, identity(rows));
    print_errors(std::string("  splat-transform vs hbgs, per splat"), e);
    if (rows == ours->size() && (e.position > 1e-5 || e.log_scale > 1e-5 || e.colour > 1e-5 || e.opacity > 1e-5 ||
                                 e.rotation_deg > (std::string(w.file) == "hbgs.splat" ? 0.91 : 0.01)))
      fail("%s%s: splat-transform and hbgs decode splats differently", tag.c_str(), w.file);
  }

  // 3. splat-transform writes from hbgs's PLY, hbgs reads.
  std::printf("\n%s[splat-transform writes from hbgs.ply, hbgs reads]\n", tag.c_str());
  const std::string ply = work + "/hbgs.ply";
  struct Converted {
    const char* file;
    const char* options;
    double min_psnr;
  };
  // splat-transform's .spz is Niantic's writer (12 fractional bits, 5/4-bit SH); its SH decode is
  // (b - 128) / 128 of a value encoded as round((c + 1) / 2 * 255): 0.4 % scale error on top of the
  // step. Bounds below: position 2^-13, SH1 1/32 + 0.9 * 0.004 + 1/256, SH2-3 1/16 + the same.
  // Its .splat (3.x) is compared with the cloud cut to SH degree 0, all the format keeps; it is
  // made from a PLY of unit quaternions: 3.7.0's .splat writer quantises q * 128 + 128 of the
  // quaternion as stored, and a 3DGS PLY's are not unit (this cloud's: |q| ~ 2, most bytes clamp,
  // rotations off by up to 67 degrees); it also truncates (floor) where hbgs rounds: colour and
  // alpha to a step of 1/255, each rotation byte to a step of 1/128, so |dq| < 2/128 and the
  // rotation within 2 asin(1/64) = 1.79 degrees.
  std::vector<Converted> converted = {{"st.spz", "--spz-version 3", 33.0},
                                      {"st_v4.spz", "", 33.0},  // the default version
                                      {"st.compressed.ply", "", 40.0}};
  if (release.writes_splat) converted.push_back({"st.splat", "", 50.0});
  GaussianCloud unit = cloud;
  for (size_t i = 0; i < unit.size(); ++i) {
    float* q = &unit.quats[4 * i];
    const float n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; ++k) q[k] /= n;
  }
  const std::string unit_ply = work + "/hbgs_unit_quaternions.ply";
  if (gs::Status st = gs::io::write_gaussians(unit_ply, unit); !st.ok()) fail("%s%s", tag.c_str(), st.to_string().c_str());
  double spz_db[2] = {0, 0};  // v3, v4
  GaussianCloud spz_read[2];
  for (const Converted& c : converted) {
    const std::string path = work + "/" + c.file;
    const std::string file = c.file;
    if (splat_transform(quote(file == "st.splat" ? unit_ply : ply) + " " + quote(path) + " " + c.options, &out) != 0) {
      fail("%ssplat-transform cannot write %s:\n%s", tag.c_str(), c.file, tail(out, 10).c_str());
      continue;
    }
    if (file == "st_v4.spz" && file_head(path, 5) != std::string("NGSP\x04", 5))
      fail("%sst_v4.spz: splat-transform's default .spz is not version 4", tag.c_str());
    if (file == "st.spz" && file_head(path, 2) != "\x1f\x8b")
      fail("%sst.spz: splat-transform's --spz-version 3 did not write gzip", tag.c_str());
    gs::io::SplatFormat format;
    gs::Expected<GaussianCloud> back = gs::io::read_gaussians(path, &format);
    if (!back.ok()) {
      fail("%shbgs cannot read splat-transform's %s: %s", tag.c_str(), c.file, back.status().to_string().c_str());
      continue;
    }
    const bool compressed = format == SplatFormat::kCompressedPly, splat = format == SplatFormat::kAntimatterSplat;
    // A raw-frame release's .spz holds the PLY's frame: hbgs (reading it as RUB, as specified)
    // gets it mirrored; mirrored back, it is compared like the others.
    if (format == SplatFormat::kSpz && release.spz_raw_frame) {
      const double raw_db = gs::io::test::psnr(scene.reference_render, gs::io::test::render_cloud(*back, scene.cam));
      std::printf("  %s as hbgs reads it (RUB): render PSNR %.2f dB; with y and z negated back:\n", c.file, raw_db);
      *back = mirrored_yz(*back);
    }
    const std::vector<size_t> match = compressed || splat ? nearest_match(cloud, *back) : identity(back->size());
    std::vector<size_t> seen(cloud.size(), 0);
    for (size_t i : match) ++seen[i];
    if (back->size() != cloud.size() || std::count(seen.begin(), seen.end(), size_t(1)) != long(cloud.size()))
      fail("%s%s: %zu splats, not a one-to-one match of the %zu written", tag.c_str(), c.file, back->size(), cloud.size());
    const FieldErrors e = field_errors(cloud, *back, match);
    const double db = gs::io::test::psnr(splat ? scene.reference_render_dc : scene.reference_render,
                                         gs::io::test::render_cloud(*back, scene.cam));
    std::printf("  %s (%.2f bytes per splat, read as %s, SH degree %d): render PSNR %.2f dB%s\n", c.file,
                double(fs::file_size(path)) / double(cloud.size()), gs::io::splat_format_name(format), back->sh_degree, db,
                splat ? " (against the cloud at SH degree 0)" : "");
    print_errors("  vs the cloud written", e);
    print_stats("  read by hbgs", stats_of(*back));
    const int degree = splat ? 0 : 3;
    if (back->sh_degree != degree) fail("%s%s: SH degree %d, %d expected", tag.c_str(), c.file, back->sh_degree, degree);
    Bounds b;
    double sh1, sh_rest, rotation = 0.4;
    if (compressed) {
      b = {2.9 / 1023 / 2, 2.3 / 1023 / 2, 0.5 / 255, 0.5 / 255};
      sh1 = sh_rest = 1.0 / 64;
    } else if (splat) {
      b = {1e-6, 1e-6, 1.0 / 255, 1.0 / 255};  // float32 position and scale, truncated 8-bit colour and alpha
      sh1 = sh_rest = 0;                       // none kept
      rotation = 1.8;                          // truncated components (above)
    } else {
      b = {std::ldexp(1.0, -13), 1.0 / 32, 0.5 / 255, spz_colour};
      sh1 = 1.0 / 32 + 0.9 * 0.004 + 1.0 / 256;
      sh_rest = 1.0 / 16 + 0.9 * 0.004 + 1.0 / 256;
    }
    const double slack = 1e-5;
    if (e.position > b.position + slack || e.log_scale > b.log_scale + slack || e.opacity > b.opacity + slack ||
        e.colour > b.colour + slack || e.rotation_deg > rotation || e.sh1 > sh1 + slack || e.sh_rest > sh_rest + slack)
      fail("%s%s: a field is outside its quantisation bound (position %g, log scale %g, opacity %g, colour %g, SH1 %g, "
           "SH2-3 %g, rotation %g deg)",
           tag.c_str(), c.file, b.position, b.log_scale, b.opacity, b.colour, sh1, sh_rest, rotation);
    compare_stats(tag + c.file + ": hbgs reading vs the cloud written", stats_of(*back), scene.truth, b);
    if (!(db >= c.min_psnr)) fail("%s%s: render PSNR %.2f dB, expected at least %.1f", tag.c_str(), c.file, db, c.min_psnr);
    if (file == "st.spz" || file == "st_v4.spz") {
      const int k = file == "st.spz" ? 0 : 1;
      spz_db[k] = db;
      spz_read[k] = std::move(back).value();
    }
  }
  // The same splats as version 4 and as version 3 render alike (the attribute bytes are the same).
  if (spz_read[0].size() > 0 && spz_read[1].size() > 0) {
    const bool same = spz_read[0].means == spz_read[1].means && spz_read[0].sh == spz_read[1].sh &&
                      spz_read[0].quats == spz_read[1].quats && spz_read[0].log_scales == spz_read[1].log_scales &&
                      spz_read[0].opacity_logits == spz_read[1].opacity_logits;
    std::printf("  st_v4.spz vs st.spz (v3): %.3f vs %.3f dB, %+.4f dB; decoded splats %s\n", spz_db[1], spz_db[0],
                spz_db[1] - spz_db[0], same ? "identical" : "differ");
    if (std::fabs(spz_db[1] - spz_db[0]) > 0.1)
      fail("%sst_v4.spz renders %.3f dB, its v3 equivalent %.3f dB: more than 0.1 dB apart", tag.c_str(), spz_db[1], spz_db[0]);
  }
  if (!release.writes_splat) {
    const int rc = splat_transform(quote(ply) + " " + quote(work + "/st.splat"), &out);
    if (rc == 0) {
      fail("%ssplat-transform %s wrote a .splat: extend this test to read it back", tag.c_str(), release.version);
    } else {
      std::printf("  st.splat: splat-transform %s cannot write .splat (\"%s\")\n", release.version,
                  out.find("Unsupported output file type") != std::string::npos ? "Unsupported output file type" : "error");
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string npm_dir, work;
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::string(argv[i]) == "--npm-dir") npm_dir = argv[i + 1];
    if (std::string(argv[i]) == "--work") work = argv[i + 1];
  }
  if (npm_dir.empty() || work.empty()) {
    std::fprintf(stderr, "usage: %s --npm-dir DIR --work DIR\n", argv[0]);
    return 2;
  }
  setvbuf(stdout, nullptr, _IOLBF, 0);

  // 1. Node and the packages (one npm install for all that are missing: one resolution, shared
  // dependencies downloaded once).
  std::string out;
  if (run("node --version", &out) != 0) {
    std::printf("SKIPPED: node is not installed (splat-transform needs Node 18 or later)\n");
    return kSkip;
  }
  std::printf("node %s", out.c_str());
  const int node_major = std::atoi(out.c_str() + (out[0] == 'v' ? 1 : 0));
  if (node_major < 18) {
    std::printf("SKIPPED: node %s is older than 18\n", out.c_str());
    return kSkip;
  }
  std::string missing;
  for (const Release& r : kReleases)
    if (!installed(npm_dir, r)) missing += std::string(" st-") + r.version + "@npm:@playcanvas/splat-transform@" + r.version;
  if (!missing.empty()) {
    if (run("npm --version", &out) != 0) {
      std::printf("SKIPPED: npm is not installed\n");
      return kSkip;
    }
    fs::create_directories(npm_dir);
    std::printf("installing%s into %s\n", missing.c_str(), npm_dir.c_str());
    // --ignore-scripts: only the JavaScript and WASM are needed (the webgpu binding's install step
    // is for GPU work this test does not do).
    if (run("npm install --prefix " + quote(npm_dir) + " --no-audit --no-fund --ignore-scripts --fetch-retries=1 " +
                "--fetch-timeout=60000" + missing,
            &out) != 0) {
      std::printf("SKIPPED: npm install%s failed (offline?):\n%s\n", missing.c_str(), tail(out, 8).c_str());
      return kSkip;
    }
  }

  fs::remove_all(work);
  fs::create_directories(work);
  Scene scene;
  scene.cloud = gs::io::test::make_test_cloud(3000, 3, 2024);
  scene.truth = stats_of(scene.cloud);
  scene.cam = gs::io::test::splat_test_camera();
  scene.reference_render = gs::io::test::render_cloud(scene.cloud, scene.cam);
  GaussianCloud dc_only = scene.cloud;  // what a .splat keeps
  dc_only.sh_degree = 0;
  dc_only.sh.resize(scene.cloud.size() * 3);
  const size_t K = size_t(gs::sh_coeff_count(scene.cloud.sh_degree));
  for (size_t i = 0; i < scene.cloud.size(); ++i)
    for (size_t ch = 0; ch < 3; ++ch) dc_only.sh[3 * i + ch] = scene.cloud.sh[i * K * 3 + ch];
  scene.reference_render_dc = gs::io::test::render_cloud(dc_only, scene.cam);
  std::printf("\ntest cloud: %zu splats, SH degree 3, seed 2024\n", scene.cloud.size());

  int ran = 0;
  for (const Release& r : kReleases) {
    const std::string cli = package_dir_of(npm_dir, r) + "/bin/cli.mjs";
    if (run("node " + quote(cli) + " --version", &out) != 0 || out.find(r.version) == std::string::npos) {
      if (r.version[0] == '3' && node_major < 22) {  // its package.json asks for node 22
        std::printf("\nSKIPPED splat-transform %s: it does not run on node %d (it asks for 22):\n%s\n", r.version, node_major,
                    tail(out, 4).c_str());
        continue;
      }
      std::printf("FAIL: %s --version: %s\n", cli.c_str(), out.c_str());
      return 1;
    }
    std::printf("\n==== splat-transform %s", out.c_str());
    check_release(r, cli, work + "/" + r.version, scene);
    ++ran;
  }
  if (ran == 0) {
    std::printf("SKIPPED: no splat-transform release runs on this node\n");
    return kSkip;
  }
  std::printf("\n%s\n", failures ? "FAILED" : "all checks passed");
  return failures ? 1 : 0;
}
