// SPDX-License-Identifier: MIT
// VideoSource tests against clips made on the spot by the ffmpeg CLI (lavfi testsrc): frame count,
// size, timestamps and sequence numbers; pixels against ffmpeg's own rgb24 extraction of the same
// frame; odd sizes, 4:4:4 and MJPEG; downscaling; and the failure modes: missing file, a text file
// named .mp4, an MP4 cut before its index, MPEG-TS and Matroska cut mid-stream (documented: frames
// up to the cut, then end of stream with truncated() set) and a frame wiped mid-stream (a decode
// error naming the frame). Without ffmpeg on PATH the tests say so and pass without checking.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "gs/capture/video_source.h"
#include "support/temp_dir.h"

namespace gs::capture {
namespace {

bool contains(const std::string& haystack, const std::string& needle) { return haystack.find(needle) != std::string::npos; }

bool have_tool(const char* tool) {
  return std::system(("command -v " + std::string(tool) + " >/dev/null 2>&1").c_str()) == 0;
}

bool have_ffmpeg() {
  static const bool ok = have_tool("ffmpeg");
  if (!ok) MESSAGE("ffmpeg is not on PATH: video source test skipped (install ffmpeg to run it)");
  return ok;
}

void run(const std::string& cmd) {
  INFO(cmd);
  REQUIRE(std::system(cmd.c_str()) == 0);
}

std::string capture_output(const std::string& cmd) {
  std::string out;
  if (FILE* p = ::popen(cmd.c_str(), "r")) {
    char buf[4096];
    size_t n;
    while ((n = std::fread(buf, 1, sizeof(buf), p)) > 0) out.append(buf, n);
    ::pclose(p);
  }
  return out;
}

std::vector<uint8_t> read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& path, const uint8_t* data, size_t size) {
  std::ofstream f(path, std::ios::binary);
  f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  REQUIRE(f.good());
}

// A 10 fps lavfi test pattern clip; `codec_args` picks the codec and pixel format.
std::string make_clip(const test::TempDir& dir, const std::string& file, const std::string& size, double seconds,
                      const std::string& codec_args) {
  const std::string path = dir / file;
  std::ostringstream cmd;
  cmd << "ffmpeg -nostdin -y -v error -f lavfi -i testsrc=duration=" << seconds << ":size=" << size << ":rate=10 "
      << codec_args << " '" << path << "'";
  run(cmd.str());
  return path;
}

// Frame n of a clip as ffmpeg's CLI decodes and converts it: packed rgb24, optionally scaled.
std::vector<uint8_t> ffmpeg_frame(const std::string& clip, int n, const std::string& scale = "") {
  const std::string out = clip + ".frame.rgb";
  run("ffmpeg -nostdin -y -v error -i '" + clip + "' -vf 'select=eq(n\\," + std::to_string(n) + ")" +
      (scale.empty() ? "" : "," + scale) + "' -frames:v 1 -f rawvideo -pix_fmt rgb24 '" + out + "'");
  return read_bytes(out);
}

struct Decoded {
  Status status;  // first error from configure/start/acquire, if any
  FrameFormat actual;
  std::vector<std::vector<uint8_t>> frames;  // packed rows (stride removed)
  std::vector<int64_t> timestamps;
  std::vector<uint64_t> sequences;
  bool truncated = false;
  VideoInfo info;
};

Decoded decode_all(const std::string& path, const FrameFormat& requested = FrameFormat{}) {
  Decoded d;
  VideoSource src(path);
  d.status = src.configure(requested, &d.actual);
  if (!d.status.ok()) return d;
  d.info = src.probe();
  d.status = src.start();
  if (!d.status.ok()) return d;
  for (int guard = 0; guard < 100000; ++guard) {
    FrameView f;
    auto r = src.acquire(-1, &f);
    if (!r.ok()) {
      d.status = r.status();
      break;
    }
    if (*r == AcquireResult::kEndOfStream) break;
    REQUIRE(validate_frame(f).ok());
    REQUIRE(f.format == PixelFormat::kRGB24);
    std::vector<uint8_t> packed(size_t(f.width) * size_t(f.height) * 3);
    for (int y = 0; y < f.height; ++y)
      std::copy_n(f.planes[0].data + size_t(y) * size_t(f.planes[0].stride), size_t(f.width) * 3,
                  packed.begin() + std::ptrdiff_t(size_t(y) * size_t(f.width) * 3));
    d.frames.push_back(std::move(packed));
    d.timestamps.push_back(f.timestamp_ns);
    d.sequences.push_back(f.sequence);
    REQUIRE(src.release(f).ok());
  }
  d.truncated = src.truncated();
  src.stop();
  return d;
}

double mean_abs_diff(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  REQUIRE(a.size() == b.size());
  REQUIRE(!a.empty());
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) sum += std::abs(int(a[i]) - int(b[i]));
  return sum / double(a.size());
}

void check_sequence(const Decoded& d) {
  for (size_t i = 0; i < d.sequences.size(); ++i) CHECK(d.sequences[i] == i);
  for (size_t i = 1; i < d.timestamps.size(); ++i) CHECK(d.timestamps[i] > d.timestamps[i - 1]);
}

// Byte offset and size of video packet `index` as ffprobe reports it; {-1, -1} without ffprobe.
std::pair<long, long> packet_position(const std::string& clip, int index) {
  if (!have_tool("ffprobe")) return {-1, -1};
  std::istringstream rows(capture_output("ffprobe -v error -select_streams v -show_entries packet=pos,size -of "
                                         "default=noprint_wrappers=1 '" + clip + "'"));
  // Lines come as size=N then pos=N for each packet.
  std::string line;
  long size = -1;
  int seen = 0;
  while (std::getline(rows, line)) {
    if (line.rfind("size=", 0) == 0) size = std::atol(line.c_str() + 5);
    if (line.rfind("pos=", 0) == 0) {
      if (seen++ == index) return {std::atol(line.c_str() + 4), size};
    }
  }
  return {-1, -1};
}

// Pixel tolerance against the ffmpeg CLI: the same libswscale converts both, so the mean absolute
// difference is normally 0; 1 level leaves room for a different scaler path or rounding.
constexpr double kMeanTolerance = 1.0;

TEST_CASE("video H.264 mp4 decodes every frame with size and timestamps") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  const std::string clip = make_clip(dir, "clip.mp4", "160x120", 1, "-pix_fmt yuv420p -c:v libx264");
  const Decoded d = decode_all(clip);
  REQUIRE_MESSAGE(d.status.ok(), d.status.to_string());
  CHECK(d.actual.width == 160);
  CHECK(d.actual.height == 120);
  CHECK(d.actual.format == PixelFormat::kRGB24);
  CHECK(d.actual.fps == doctest::Approx(10.0));
  CHECK(d.info.width == 160);
  CHECK(d.info.height == 120);
  CHECK(d.info.fps == doctest::Approx(10.0));
  CHECK(d.info.frame_count == 10);
  CHECK(d.info.duration_s == doctest::Approx(1.0).epsilon(0.05));
  CHECK(d.info.codec == "h264");
  REQUIRE(d.frames.size() == 10);
  CHECK_FALSE(d.truncated);
  check_sequence(d);
  for (size_t i = 0; i < d.timestamps.size(); ++i)  // 10 fps from the first frame at 0
    CHECK(std::llabs(d.timestamps[i] - int64_t(i) * 100000000) < 1000000);
}

TEST_CASE("video frame pixels match the ffmpeg CLI rgb24 extraction") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  const std::string clip = make_clip(dir, "clip.mp4", "160x120", 1, "-pix_fmt yuv420p -c:v libx264");
  const Decoded d = decode_all(clip);
  REQUIRE_MESSAGE(d.status.ok(), d.status.to_string());
  REQUIRE(d.frames.size() == 10);
  const std::vector<uint8_t> reference = ffmpeg_frame(clip, 3);
  const double mad = mean_abs_diff(d.frames[3], reference);
  MESSAGE("frame 3 mean abs diff vs ffmpeg CLI: " << mad);
  CHECK(mad <= kMeanTolerance);
  // The pattern moves little between frames, so show the comparison picks out frame 3 itself.
  CHECK(mad < mean_abs_diff(d.frames[2], reference));
  CHECK(mad < mean_abs_diff(d.frames[4], reference));
}

TEST_CASE("video odd sizes and 4:4:4 and MJPEG clips decode") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  struct Case {
    const char* file;
    const char* size;
    const char* args;
    int w, h;
    const char* codec;
  };
  const Case cases[] = {
      {"even.mkv", "162x122", "-pix_fmt yuv420p -c:v libx264", 162, 122, "h264"},
      {"odd444.mkv", "161x121", "-pix_fmt yuv444p -c:v libx264", 161, 121, "h264"},
      {"odd.avi", "161x121", "-c:v mjpeg", 161, 121, "mjpeg"},  // full-range yuvj420p
  };
  for (const Case& c : cases) {
    const std::string file = c.file;
    CAPTURE(file);
    const std::string clip = make_clip(dir, c.file, c.size, 1, c.args);
    const Decoded d = decode_all(clip);
    REQUIRE_MESSAGE(d.status.ok(), d.status.to_string());
    CHECK(d.actual.width == c.w);
    CHECK(d.actual.height == c.h);
    CHECK(d.info.codec == c.codec);
    REQUIRE(d.frames.size() == 10);
    check_sequence(d);
    CHECK_FALSE(d.truncated);
    const double mad = mean_abs_diff(d.frames[5], ffmpeg_frame(clip, 5));
    MESSAGE(file << " frame 5 mean abs diff vs ffmpeg CLI: " << mad);
    CHECK(mad <= kMeanTolerance);
  }
}

TEST_CASE("video downscale request delivers the smaller size") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  const std::string clip = make_clip(dir, "clip.mp4", "160x120", 1, "-pix_fmt yuv420p -c:v libx264");
  FrameFormat req;
  req.width = 80;
  req.height = 60;
  const Decoded d = decode_all(clip, req);
  REQUIRE_MESSAGE(d.status.ok(), d.status.to_string());
  CHECK(d.actual.width == 80);
  CHECK(d.actual.height == 60);
  REQUIRE(d.frames.size() == 10);
  CHECK(d.frames[0].size() == size_t(80 * 60 * 3));
  // Both sides use libswscale's bicubic scaler; allow a little more for its chroma handling.
  const double mad = mean_abs_diff(d.frames[4], ffmpeg_frame(clip, 4, "scale=80:60"));
  MESSAGE("downscaled frame 4 mean abs diff vs ffmpeg CLI: " << mad);
  CHECK(mad <= 2 * kMeanTolerance);

  VideoSource src(clip);
  FrameFormat actual, bigger, one_side;
  bigger.width = 320;
  bigger.height = 240;
  const Status st = src.configure(bigger, &actual);
  REQUIRE_FALSE(st.ok());
  CHECK(contains(st.message(), "only downscaling"));
  one_side.width = 80;
  CHECK_FALSE(src.configure(one_side, &actual).ok());
}

TEST_CASE("video acquire and release follow the FrameSource contract") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  const std::string clip = make_clip(dir, "clip.mp4", "160x120", 0.3, "-pix_fmt yuv420p -c:v libx264");
  VideoSource src(clip);
  CHECK(std::string(src.name()) == "video:" + clip);
  FrameView f, g;
  CHECK_FALSE(src.start().ok());  // not configured
  FrameFormat actual;
  REQUIRE(src.configure(FrameFormat{}, &actual).ok());
  CHECK_FALSE(src.acquire(0, &f).ok());  // not started
  REQUIRE(src.start().ok());
  REQUIRE(*src.acquire(0, &f) == AcquireResult::kFrame);
  CHECK_FALSE(src.acquire(0, &g).ok());  // one frame out at a time
  FrameView foreign = f;
  foreign.planes[0].data = nullptr;
  CHECK_FALSE(src.release(foreign).ok());
  REQUIRE(src.release(f).ok());
  CHECK_FALSE(src.release(f).ok());  // twice
  int frames = 1;
  for (;;) {
    auto r = src.acquire(0, &f);
    REQUIRE(r.ok());
    if (*r == AcquireResult::kEndOfStream) break;
    ++frames;
    REQUIRE(src.release(f).ok());
  }
  CHECK(frames == 3);
  CHECK(src.frames_decoded() == 3);
  auto again = src.acquire(0, &f);  // end of stream is sticky
  REQUIRE(again.ok());
  CHECK(*again == AcquireResult::kEndOfStream);
  CHECK(src.stop().ok());
}

TEST_CASE("video missing file and non-video file are configure errors") {
  test::TempDir dir("gs_video");
  FrameFormat actual;
  {
    VideoSource src(dir / "absent.mp4");
    const Status st = src.configure(FrameFormat{}, &actual);
    REQUIRE_FALSE(st.ok());
    CHECK(contains(st.message(), "absent.mp4"));
    CHECK(contains(st.message(), "no such file"));
  }
  {
    const std::string text = "This is a text file with an mp4 name.\n";
    write_bytes(dir / "text.mp4", reinterpret_cast<const uint8_t*>(text.data()), text.size());
    VideoSource src(dir / "text.mp4");
    const Status st = src.configure(FrameFormat{}, &actual);
    REQUIRE_FALSE(st.ok());
    CHECK(contains(st.message(), "text.mp4"));
    MESSAGE("text file: " << st.to_string());
  }
  {
    VideoSource src(dir.path());
    CHECK_FALSE(src.configure(FrameFormat{}, &actual).ok());
  }
}

TEST_CASE("video mp4 cut before its moov index fails at configure") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  const std::string clip = make_clip(dir, "clip.mp4", "160x120", 1, "-pix_fmt yuv420p -c:v libx264");
  const std::vector<uint8_t> bytes = read_bytes(clip);
  write_bytes(dir / "cut.mp4", bytes.data(), bytes.size() * 3 / 10);  // ffmpeg writes moov at the end
  VideoSource src(dir / "cut.mp4");
  FrameFormat actual;
  const Status st = src.configure(FrameFormat{}, &actual);
  REQUIRE_FALSE(st.ok());
  CHECK(contains(st.message(), "cut.mp4"));
  MESSAGE("cut mp4: " << st.to_string());
}

TEST_CASE("video mpeg-ts cut inside a frame ends early with truncated set") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  // Keyframes every 5 frames so a cut leaves decodable frames behind it.
  const std::string clip = make_clip(dir, "clip.ts", "160x120", 2, "-pix_fmt yuv420p -c:v libx264 -g 5");
  const std::vector<uint8_t> bytes = read_bytes(clip);
  auto pos = packet_position(clip, 5);  // the second keyframe, the largest packet
  if (pos.first < 0) {
    MESSAGE("ffprobe not available: cutting mpeg-ts at half its size instead of inside frame 5");
    pos = {long(bytes.size() / 2), 0};
  }
  const size_t cut = size_t(pos.first + pos.second / 2);
  REQUIRE(cut < bytes.size());
  write_bytes(dir / "cut.ts", bytes.data(), cut);
  const Decoded d = decode_all(dir / "cut.ts");
  REQUIRE_MESSAGE(d.status.ok(), d.status.to_string());  // documented: frames up to the cut, no error
  CHECK(d.frames.size() >= 1);
  CHECK(d.frames.size() < 20);
  check_sequence(d);
  if (pos.second > 0) {
    CHECK(d.frames.size() >= 5);  // everything before the damaged frame
    CHECK(d.frames.size() <= 6);  // and possibly the concealed frame itself
    CHECK(d.truncated);
  }
}

TEST_CASE("video matroska cut in the middle ends early with truncated set") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  const std::string clip = make_clip(dir, "clip.mkv", "160x120", 2, "-pix_fmt yuv420p -c:v libx264 -g 5");
  const std::vector<uint8_t> bytes = read_bytes(clip);
  write_bytes(dir / "cut.mkv", bytes.data(), bytes.size() / 2);
  const Decoded d = decode_all(dir / "cut.mkv");
  REQUIRE_MESSAGE(d.status.ok(), d.status.to_string());
  CHECK(d.info.frame_count == 20);  // the header still promises the whole clip
  CHECK(d.frames.size() >= 1);
  CHECK(d.frames.size() < 20);
  CHECK(d.truncated);
  check_sequence(d);

  // Cut so early that no frame survives: an error, not an empty stream.
  write_bytes(dir / "stub.mkv", bytes.data(), bytes.size() / 10);
  VideoSource src(dir / "stub.mkv");
  FrameFormat actual;
  Status st = src.configure(FrameFormat{}, &actual);
  if (st.ok()) {
    REQUIRE(src.start().ok());
    FrameView f;
    auto r = src.acquire(-1, &f);
    REQUIRE_FALSE(r.ok());
    st = r.status();
  }
  CHECK(contains(st.message(), "stub.mkv"));
  MESSAGE("stub mkv: " << st.to_string());
}

TEST_CASE("video frame wiped mid-stream is a decode error naming the frame") {
  if (!have_ffmpeg()) return;
  test::TempDir dir("gs_video");
  const std::string clip = make_clip(dir, "clip.avi", "160x120", 1, "-c:v mjpeg");
  const auto pos = packet_position(clip, 5);
  if (pos.first < 0) {
    MESSAGE("ffprobe not on PATH: mid-stream decode error test skipped");
    return;
  }
  std::vector<uint8_t> bytes = read_bytes(clip);
  REQUIRE(size_t(pos.first + pos.second) <= bytes.size());
  std::fill_n(bytes.begin() + pos.first, pos.second, uint8_t(0));  // container intact, JPEG gone
  write_bytes(dir / "wiped.avi", bytes.data(), bytes.size());
  const Decoded d = decode_all(dir / "wiped.avi");
  REQUIRE_FALSE(d.status.ok());
  CHECK(d.frames.size() == 5);
  CHECK(contains(d.status.message(), "wiped.avi"));
  CHECK(contains(d.status.message(), "decode error at frame 5"));
  MESSAGE("wiped frame: " << d.status.to_string());
}

}  // namespace
}  // namespace gs::capture
