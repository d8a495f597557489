// SPDX-License-Identifier: MIT
// Shared pieces of the benchmarks: the seeded synthetic Gaussian scene (uniform in a camera
// frustum, splats a few pixels wide at any resolution), the machine description (CPU model,
// frequency), the kernel tables to compare, and small list parsers for the command lines.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "gs/camera.h"
#include "gs/platform/file.h"
#include "gs/render.h"
#include "gs/simd/kernel_table.h"

namespace gs::bench {

// Pinhole camera at the origin looking down +z (about 64 degrees horizontal field of view).
inline Camera synthetic_camera(int width, int height) {
  Camera c;
  c.intr.width = width;
  c.intr.height = height;
  c.intr.fx = c.intr.fy = 0.8f * float(width);
  c.intr.cx = 0.5f * float(width);
  c.intr.cy = 0.5f * float(height);
  return c;
}

struct SyntheticScene : ColoredGaussians {
  Camera camera;
};

// Gaussians uniform in volume inside the view frustum between depths 2 and 10 (depth drawn with
// density ~ z^2, then a uniform pixel position), per-axis world sigma = U(0.5, 2.5) * z / fx so
// the projected sigma is 0.5-2.5 px before dilation whatever the resolution, uniform random
// rotations, opacity U(0.1, 0.9), colours U(0, 1).
inline SyntheticScene synthetic_scene(const Camera& camera, size_t count, uint64_t seed) {
  SyntheticScene s;
  s.camera = camera;
  s.resize(count);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> nrm(0.0, 1.0);
  const PinholeIntrinsics& in = camera.intr;
  const double z0 = 2.0, z1 = 10.0;
  for (size_t i = 0; i < count; ++i) {
    const double z = std::cbrt(z0 * z0 * z0 + u01(rng) * (z1 * z1 * z1 - z0 * z0 * z0));
    const double px = in.width * u01(rng), py = in.height * u01(rng);
    s.means[3 * i + 0] = float((px - in.cx) / in.fx * z);
    s.means[3 * i + 1] = float((py - in.cy) / in.fy * z);
    s.means[3 * i + 2] = float(z);
    for (int k = 0; k < 3; ++k) s.log_scales[3 * i + k] = float(std::log((0.5 + 2.0 * u01(rng)) * z / in.fx));
    double q[4], qn = 0;
    do {
      qn = 0;
      for (double& v : q) v = nrm(rng), qn += v * v;
    } while (qn < 1e-12);
    qn = std::sqrt(qn);
    for (int k = 0; k < 4; ++k) s.quats[4 * i + k] = float(q[k] / qn);
    s.opacities[i] = float(0.1 + 0.8 * u01(rng));
    for (int k = 0; k < 3; ++k) s.colors[3 * i + k] = float(u01(rng));
  }
  return s;
}

// The ref table plus every SIMD table this build and CPU support, ref first.
inline std::vector<const simd::KernelTable*> all_kernel_tables() {
  std::vector<const simd::KernelTable*> out{&simd::ref_kernel_table()};
  const simd::KernelTable* simd_tables[16];
  const int n = simd::available_simd_kernel_tables(simd_tables, 16);
  // available_simd_kernel_tables lists best first; print narrowest first so rows read ref -> best.
  for (int i = n - 1; i >= 0; --i) out.push_back(simd_tables[i]);
  return out;
}

struct MachineInfo {
  std::string cpu_model = "unknown";
  double cpu_mhz = 0;      // current frequency of CPU 0 as /proc/cpuinfo reports it (0: not readable)
  double max_mhz = 0;      // cpufreq scaling_max_freq (0: not readable, e.g. in a VM)
  unsigned hw_threads = 0;
};

inline MachineInfo machine_info() {
  MachineInfo m;
  m.hw_threads = std::thread::hardware_concurrency();
  std::ifstream f("/proc/cpuinfo");
  std::string line;
  bool have_model = false, have_mhz = false;
  while (std::getline(f, line) && !(have_model && have_mhz)) {
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string key = line.substr(0, colon);
    while (!key.empty() && (key.back() == ' ' || key.back() == '\t')) key.pop_back();
    std::string value = line.substr(colon + 1);
    while (!value.empty() && value.front() == ' ') value.erase(value.begin());
    if (!have_model && (key == "model name" || key == "Model" || key == "Hardware")) {
      m.cpu_model = value;
      have_model = true;
    } else if (!have_mhz && key == "cpu MHz") {
      m.cpu_mhz = std::atof(value.c_str());
      have_mhz = true;
    }
  }
  std::ifstream fm("/sys/devices/system/cpu/cpu0/cpufreq/scaling_max_freq");
  double khz = 0;
  if (fm >> khz) m.max_mhz = khz / 1000.0;
  return m;
}

// 1-minute load average (-1 where unreadable). Above the hardware thread count, other processes
// compete for the CPUs and wall times inflate; CPU times stay closer to the work done.
inline double load_average() {
  std::ifstream f("/proc/loadavg");
  double v = -1;
  if (!(f >> v)) return -1;
  return v;
}

inline std::string format_mhz(const MachineInfo& m) {
  char buf[96];
  if (m.cpu_mhz > 0 && m.max_mhz > 0)
    std::snprintf(buf, sizeof(buf), "%.0f MHz (max %.0f MHz)", m.cpu_mhz, m.max_mhz);
  else if (m.cpu_mhz > 0)
    std::snprintf(buf, sizeof(buf), "%.0f MHz (cpufreq not readable)", m.cpu_mhz);
  else
    std::snprintf(buf, sizeof(buf), "not readable");
  return buf;
}

// Comma-separated list helpers for the command lines; throw std::invalid_argument on bad input.
inline std::vector<std::string> split_list(const std::string& s) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == ',') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else if (c != ' ') {
      cur += c;
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

// "10000", "10k", "1M", "2.5M".
inline size_t parse_count(const std::string& s) {
  size_t pos = 0;
  const double v = std::stod(s, &pos);
  double mult = 1;
  const std::string rest = s.substr(pos);
  if (rest == "k" || rest == "K") mult = 1e3;
  else if (rest == "m" || rest == "M") mult = 1e6;
  else if (!rest.empty()) throw std::invalid_argument("bad count '" + s + "' (use e.g. 10000, 100k, 1M)");
  if (!(v > 0)) throw std::invalid_argument("count must be positive: '" + s + "'");
  return size_t(std::llround(v * mult));
}

// "WxH".
inline void parse_size(const std::string& s, int* w, int* h) {
  const size_t x = s.find_first_of("xX");
  if (x == std::string::npos) throw std::invalid_argument("bad size '" + s + "' (use WxH, e.g. 320x240)");
  *w = std::stoi(s.substr(0, x));
  *h = std::stoi(s.substr(x + 1));
  if (*w < 1 || *h < 1 || *w > 16384 || *h > 16384) throw std::invalid_argument("size out of range: '" + s + "'");
}

inline std::string count_label(size_t n) {
  char buf[32];
  if (n >= 1000000 && n % 1000000 == 0) std::snprintf(buf, sizeof(buf), "%zuM", n / 1000000);
  else if (n >= 1000 && n % 1000 == 0) std::snprintf(buf, sizeof(buf), "%zuk", n / 1000);
  else std::snprintf(buf, sizeof(buf), "%zu", n);
  return buf;
}

// Writes a benchmark's JSON (or any text output) atomically through the platform layer and says
// where it went; returns false (after printing why) if it could not.
inline bool write_output(const std::string& path, const std::string& text, const char* program) {
  const Status st = platform::write_file_atomic(path, text);
  if (!st.ok()) {
    std::fprintf(stderr, "%s: cannot write %s: %s\n", program, path.c_str(), st.to_string().c_str());
    return false;
  }
  std::printf("Wrote %s\n", path.c_str());
  return true;
}

}  // namespace gs::bench
