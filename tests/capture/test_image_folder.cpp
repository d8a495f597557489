// SPDX-License-Identifier: MIT
// ImageFolderSource tests: which files count as images (extension, any case; other files and
// folders ignored), name order, pixel content and synthetic timestamps, and the errors for a
// missing or empty folder, an image of another size and an unreadable image.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "gs/capture/image_folder_source.h"
#include "gs/io/image.h"
#include "support/temp_dir.h"

namespace gs::capture {
namespace {

bool contains(const std::string& haystack, const std::string& needle) { return haystack.find(needle) != std::string::npos; }

// A w x h RGB image whose every pixel is (v, 2v, 255 - v), so each file is recognisable.
void write_flat_png(const std::string& path, int w, int h, uint8_t v) {
  io::Image8 img{w, h, 3, std::vector<uint8_t>(size_t(w) * size_t(h) * 3)};
  for (size_t i = 0; i < img.pixels.size(); i += 3) {
    img.pixels[i] = v;
    img.pixels[i + 1] = uint8_t(2 * v);
    img.pixels[i + 2] = uint8_t(255 - v);
  }
  REQUIRE(io::write_png(path, img).ok());
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
  REQUIRE(f.good());
}

TEST_CASE("image folder delivers images in name order with synthetic timestamps") {
  test::TempDir dir("gs_imgdir");
  // PNG data under every accepted extension spelling: the decoder goes by content.
  write_flat_png(dir / "frame_010.png", 9, 7, 40);
  write_flat_png(dir / "frame_000.png", 9, 7, 10);
  write_flat_png(dir / "frame_002.jpeg", 9, 7, 30);
  write_flat_png(dir / "frame_001.JPG", 9, 7, 20);
  write_text(dir / "notes.txt", "not an image");
  write_text(dir / "frame_003.png.bak", "not an image either");
  std::filesystem::create_directory(dir / "sub.png");  // a folder with an image-like name

  ImageFolderSource src(dir.path(), 10.0);
  FrameFormat req, actual;
  REQUIRE(src.configure(req, &actual).ok());
  CHECK(actual.width == 9);
  CHECK(actual.height == 7);
  CHECK(actual.format == PixelFormat::kRGB24);
  CHECK(actual.fps == doctest::Approx(10.0));
  REQUIRE(src.count() == 4);
  CHECK(src.file_name(0) == "frame_000.png");
  CHECK(src.file_name(1) == "frame_001.JPG");
  CHECK(src.file_name(2) == "frame_002.jpeg");
  CHECK(src.file_name(3) == "frame_010.png");
  REQUIRE(src.start().ok());

  const uint8_t expected[4] = {10, 20, 30, 40};
  for (int i = 0; i < 4; ++i) {
    FrameView f;
    auto r = src.acquire(0, &f);
    REQUIRE_MESSAGE(r.ok(), r.status().to_string());
    REQUIRE(*r == AcquireResult::kFrame);
    CHECK(validate_frame(f).ok());
    CHECK(f.sequence == uint64_t(i));
    CHECK(f.timestamp_ns == int64_t(i) * 100000000);
    CHECK(f.planes[0].data[0] == expected[i]);
    CHECK(f.planes[0].data[1] == uint8_t(2 * expected[i]));
    CHECK(f.planes[0].data[3 * 9 * 7 - 1] == uint8_t(255 - expected[i]));
    // Holding a frame blocks the next acquire until release.
    FrameView other;
    CHECK_FALSE(src.acquire(0, &other).ok());
    REQUIRE(src.release(f).ok());
  }
  FrameView f;
  auto end = src.acquire(0, &f);
  REQUIRE(end.ok());
  CHECK(*end == AcquireResult::kEndOfStream);
  CHECK(src.stop().ok());
}

TEST_CASE("image folder default rate is 30 fps and resizing is refused") {
  test::TempDir dir("gs_imgdir");
  write_flat_png(dir / "a.png", 4, 4, 1);
  write_flat_png(dir / "b.png", 4, 4, 2);
  ImageFolderSource src(dir.path());
  FrameFormat req, actual;
  req.width = 2;
  req.height = 2;
  const Status bad = src.configure(req, &actual);
  REQUIRE_FALSE(bad.ok());
  CHECK(contains(bad.message(), "4x4"));
  REQUIRE(src.configure(FrameFormat{}, &actual).ok());
  CHECK(actual.fps == doctest::Approx(30.0));
  REQUIRE(src.start().ok());
  FrameView f;
  REQUIRE(src.acquire(0, &f).ok());
  REQUIRE(src.release(f).ok());
  REQUIRE(src.acquire(0, &f).ok());
  CHECK(f.timestamp_ns == 33333333);
  REQUIRE(src.release(f).ok());
}

TEST_CASE("image folder image of another size is an error naming the file") {
  test::TempDir dir("gs_imgdir");
  write_flat_png(dir / "0.png", 8, 6, 1);
  write_flat_png(dir / "1.png", 8, 6, 2);
  write_flat_png(dir / "2.png", 6, 8, 3);
  ImageFolderSource src(dir.path());
  FrameFormat actual;
  REQUIRE(src.configure(FrameFormat{}, &actual).ok());
  REQUIRE(src.start().ok());
  FrameView f;
  for (int i = 0; i < 2; ++i) {
    auto r = src.acquire(0, &f);
    REQUIRE(r.ok());
    REQUIRE(src.release(f).ok());
  }
  auto r = src.acquire(0, &f);
  REQUIRE_FALSE(r.ok());
  CHECK(contains(r.status().message(), "2.png"));
  CHECK(contains(r.status().message(), "6x8"));
  CHECK(contains(r.status().message(), "8x6"));
  CHECK_FALSE(src.acquire(0, &f).ok());  // the source stays failed
}

TEST_CASE("image folder unreadable image is an error naming the file") {
  test::TempDir dir("gs_imgdir");
  write_flat_png(dir / "0.png", 8, 6, 1);
  write_text(dir / "1.png", "this is not a PNG");
  {
    ImageFolderSource src(dir.path());
    FrameFormat actual;
    REQUIRE(src.configure(FrameFormat{}, &actual).ok());
    REQUIRE(src.start().ok());
    FrameView f;
    REQUIRE(src.acquire(0, &f).ok());
    REQUIRE(src.release(f).ok());
    auto r = src.acquire(0, &f);
    REQUIRE_FALSE(r.ok());
    CHECK(contains(r.status().message(), "1.png"));
  }
  // The first image unreadable: configure already fails, naming it.
  test::TempDir dir2("gs_imgdir");
  write_text(dir2 / "00.png", "");
  write_flat_png(dir2 / "01.png", 8, 6, 1);
  ImageFolderSource src(dir2.path());
  FrameFormat actual;
  const Status st = src.configure(FrameFormat{}, &actual);
  REQUIRE_FALSE(st.ok());
  CHECK(contains(st.message(), "00.png"));
}

TEST_CASE("image folder missing or empty folder is an error") {
  test::TempDir dir("gs_imgdir");
  FrameFormat actual;
  {
    ImageFolderSource src(dir.path());
    const Status st = src.configure(FrameFormat{}, &actual);
    REQUIRE_FALSE(st.ok());
    CHECK(contains(st.message(), "no .png"));
    CHECK_FALSE(src.start().ok());
  }
  write_text(dir / "readme.txt", "only text here");
  {
    ImageFolderSource src(dir.path());
    CHECK_FALSE(src.configure(FrameFormat{}, &actual).ok());
  }
  {
    ImageFolderSource src(dir / "missing");
    const Status st = src.configure(FrameFormat{}, &actual);
    REQUIRE_FALSE(st.ok());
    CHECK(contains(st.message(), "no such folder"));
  }
  {
    ImageFolderSource src(dir / "readme.txt");
    const Status st = src.configure(FrameFormat{}, &actual);
    REQUIRE_FALSE(st.ok());
    CHECK(contains(st.message(), "not a directory"));
  }
}

}  // namespace
}  // namespace gs::capture
