// SPDX-License-Identifier: MIT
// bench_mjpeg: MJPEG frame decoding, hbgs's path (gs::capture::frame_to_rgb: marker walk, the
// Annex K Huffman tables inserted when the frame has none, stb_image) against libjpeg-turbo's
// TurboJPEG API (tjDecompress2 on the frame as the camera sent it), single thread. Frames are
// photos of the shared dataset tiled to 640x480, 1280x720 and 1920x1080, JPEG-encoded (quality 85,
// 4:2:0 as stb writes it) and stripped of their DHT segment as UVC cameras send them. Reports ms
// per frame (median and min), whether TurboJPEG decodes the stripped frame to the same pixels as
// the frame with its tables, the two decoders' PSNR against each other and against the source,
// what each does with a frame cut in half, and for scale the PNG encoding `hbgs capture` does next
// with every frame it keeps (io::encode_png).
//   bench_mjpeg [--images DIR] [--reps N] [--json FILE]
#include <turbojpeg.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "bench_common.h"
#include "bench_harness.h"
#include "gs/capture/convert.h"
#include "gs/io/image.h"
#include "gs/metrics/image_metrics.h"

namespace gs::bench {
namespace {

// The JPEG without its DHT segments (what a UVC camera sends).
std::vector<uint8_t> strip_dht(const std::vector<uint8_t>& j) {
  std::vector<uint8_t> out(j.begin(), j.begin() + 2);
  size_t pos = 2;
  while (pos + 4 <= j.size() && j[pos] == 0xff) {
    const uint8_t m = j[pos + 1];
    const size_t len = 2 + (size_t(j[pos + 2]) << 8 | j[pos + 3]);
    if (m != 0xc4) out.insert(out.end(), j.begin() + long(pos), j.begin() + long(pos + len));
    pos += len;
    if (m == 0xda) break;
  }
  out.insert(out.end(), j.begin() + long(pos), j.end());
  return out;
}

// gs::metrics: +inf (JSON null) for identical decodes.
double psnr8(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  return a.size() == b.size() ? metrics::psnr_u8(a.data(), b.data(), a.size()) : std::nan("");
}

// A w x h picture tiled from the dataset's photos (each one whole, cropped at the right and bottom edges).
io::Image8 mosaic(const std::vector<io::Image8>& photos, int w, int h) {
  io::Image8 m;
  m.width = w;
  m.height = h;
  m.channels = 3;
  m.pixels.assign(size_t(w) * size_t(h) * 3, 0);
  size_t k = 0;
  for (int y0 = 0; y0 < h; y0 += photos[0].height)
    for (int x0 = 0; x0 < w; x0 += photos[0].width, ++k) {
      const io::Image8& p = photos[k % photos.size()];
      for (int y = 0; y < p.height && y0 + y < h; ++y)
        for (int x = 0; x < p.width && x0 + x < w; ++x)
          for (int c = 0; c < 3; ++c)
            m.pixels[(size_t(y0 + y) * size_t(w) + size_t(x0 + x)) * 3 + size_t(c)] = p.pixels[(size_t(y) * size_t(p.width) + size_t(x)) * 3 + size_t(c)];
    }
  return m;
}

int run(int argc, char** argv) {
  CLI::App app{"bench_mjpeg: MJPEG frame decoding, hbgs (stb_image + inserted Huffman tables) vs libjpeg-turbo"};
  std::string images = std::string(GS_BENCH_DEFAULT_IMAGES), json_path;
  int reps = 30;
  app.add_option("--images", images, "folder of JPEG photos to tile into frames")->capture_default_str();
  app.add_option("--reps", reps, "timed repetitions per case")->check(CLI::PositiveNumber);
  app.add_option("--json", json_path, "also write the figures as JSON to this file");
  CLI11_PARSE(app, argc, argv);

  std::vector<io::Image8> photos;
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(images)) names.push_back(e.path().string());
  std::sort(names.begin(), names.end());
  for (const std::string& n : names) {
    if (photos.size() == 9) break;
    Expected<io::Image8> img = io::read_image(n, 3);
    if (img.ok()) photos.push_back(std::move(img).value());
  }
  if (photos.empty()) {
    std::fprintf(stderr, "bench_mjpeg: no images in %s\n", images.c_str());
    return 1;
  }
  const MachineInfo mi = machine_info();
  std::printf("bench_mjpeg: %s, %s, load average %.2f; frames tiled from %zu photos of %s (%dx%d)\n", mi.cpu_model.c_str(),
              format_mhz(mi).c_str(), load_average(), photos.size(), images.c_str(), photos[0].width, photos[0].height);
  HarnessOptions ho;
  ho.warmup = 2;
  ho.reps = reps;
  ho.min_reps = 5;
  ho.max_seconds = 2.0;
  tjhandle tj = tjInitDecompress();
  nlohmann::json rows = nlohmann::json::array();
  std::printf("  %-10s %8s %16s %16s %8s %10s %10s %12s %10s\n", "size", "bytes", "hbgs ms med/min", "turbo ms med/min",
              "speed-up", "turbo=DHT", "PSNR a/b", "vs source", "PNG ms min");
  const int sizes[3][2] = {{640, 480}, {1280, 720}, {1920, 1080}};
  bool all_ok = true;
  for (const auto& s : sizes) {
    const int w = s[0], h = s[1];
    const io::Image8 src = mosaic(photos, w, h);
    Expected<std::vector<uint8_t>> jpg = io::encode_jpeg(src, 85);
    if (!jpg.ok()) return 1;
    const std::vector<uint8_t> uvc = strip_dht(*jpg);
    capture::FrameView f;
    f.format = capture::PixelFormat::kMJPEG;
    f.width = w;
    f.height = h;
    f.num_planes = 1;
    f.planes[0] = {uvc.data(), uvc.size(), 0};
    std::vector<uint8_t> ours(size_t(w) * size_t(h) * 3), turbo(ours.size()), turbo_dht(ours.size());
    bool ok = true;
    const Timing t_ours = measure([&] { ok &= capture::frame_to_rgb(f, ours.data(), 3 * w).ok(); }, ho);
    const Timing t_turbo = measure(
        [&] { ok &= tjDecompress2(tj, uvc.data(), (unsigned long)uvc.size(), turbo.data(), w, 3 * w, h, TJPF_RGB, 0) == 0; }, ho);
    ok &= tjDecompress2(tj, jpg->data(), (unsigned long)jpg->size(), turbo_dht.data(), w, 3 * w, h, TJPF_RGB, 0) == 0;
    const bool same = turbo == turbo_dht;
    HarnessOptions few = ho;
    few.reps = 3;
    few.warmup = 0;
    io::Image8 decoded = src;
    decoded.pixels = ours;
    const Timing t_png = measure([&] { ok &= io::encode_png(decoded).ok(); }, few);
    const double between = psnr8(ours, turbo), ours_src = psnr8(ours, src.pixels), turbo_src = psnr8(turbo, src.pixels);
    const std::string size = std::to_string(w) + "x" + std::to_string(h);
    std::printf("  %-10s %8zu %7.2f / %6.2f %7.2f / %6.2f %7.2fx %10s %10.2f %5.2f/%5.2f %10.1f%s\n", size.c_str(), uvc.size(),
                t_ours.median_ms, t_ours.min_ms, t_turbo.median_ms, t_turbo.min_ms, t_ours.min_ms / t_turbo.min_ms,
                same ? "yes" : "NO", between, ours_src, turbo_src, t_png.min_ms, ok ? "" : "  DECODE FAILED");
    all_ok &= ok && same;
    rows.push_back({{"width", w}, {"height", h}, {"frame_bytes", uvc.size()}, {"hbgs_ms_median", t_ours.median_ms},
                    {"hbgs_ms_min", t_ours.min_ms}, {"turbo_ms_median", t_turbo.median_ms}, {"turbo_ms_min", t_turbo.min_ms},
                    {"turbo_same_without_dht", same}, {"psnr_hbgs_vs_turbo", between}, {"psnr_hbgs_vs_source", ours_src},
                    {"psnr_turbo_vs_source", turbo_src}, {"png_encode_ms_min", t_png.min_ms}});
    if (w == 640) {  // a frame cut short in transfer
      const std::vector<uint8_t> cut(uvc.begin(), uvc.begin() + long(uvc.size() / 2));
      capture::FrameView fc = f;
      fc.planes[0] = {cut.data(), cut.size(), 0};
      const Status st = capture::frame_to_rgb(fc, ours.data(), 3 * w);
      const int rc = tjDecompress2(tj, cut.data(), (unsigned long)cut.size(), turbo.data(), w, 3 * w, h, TJPF_RGB, 0);
      std::printf("  half a 640x480 frame: hbgs %s; turbo returns %d (%s: %s)\n", st.ok() ? "decodes it" : st.message().c_str(), rc,
                  tjGetErrorCode(tj) == TJERR_WARNING ? "warning" : "error", tjGetErrorStr2(tj));
    }
  }
  tjDestroy(tj);
  if (!json_path.empty() &&
      !write_output(json_path, nlohmann::json{{"tool", "bench_mjpeg"}, {"cpu", mi.cpu_model}, {"rows", rows}}.dump(2) + "\n",
                    "bench_mjpeg"))
    return 1;
  return all_ok ? 0 : 1;
}

}  // namespace
}  // namespace gs::bench

int main(int argc, char** argv) { return gs::bench::run(argc, argv); }
