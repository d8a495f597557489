// SPDX-License-Identifier: MIT
// Tests for hbgs synth --object (generate_object): the subject is wholly inside every image with a
// transparent background, alpha is the exact coverage and masks/ repeat it, the COLMAP and the
// transforms.json versions load to the same views (poses to 1e-5, intrinsics, split, pixels,
// masks), the random points of the transforms version lie in every camera's view around the
// subject, and the cluttered variant's masks mark the subject on its background.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "gs/io/colmap.h"
#include "gs/io/image.h"
#include "hbgs/synth.h"
#include "support/temp_dir.h"

namespace {

using gs::io::DatasetLayout;
using gs::io::DatasetOptions;
using gs::io::DatasetView;
using gs::test::TempDir;
using hbgs::synth::generate_object;
using hbgs::synth::ObjectOptions;

ObjectOptions small_object() {
  ObjectOptions o;
  o.width = 64;
  o.height = 56;
  o.views = 16;
  o.num_points = 800;
  return o;
}

gs::io::Dataset load(const std::string& root, DatasetLayout layout) {
  DatasetOptions opt;
  opt.layout = layout;
  auto ds = gs::io::load_dataset(root, opt);
  REQUIRE_MESSAGE(ds.ok(), ds.status().to_string());
  return std::move(ds).value();
}

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  REQUIRE(f.good());
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void project(const gs::Camera& c, const double X[3], double* u, double* v, double* z) {
  double p[3];
  for (int r = 0; r < 3; ++r) p[r] = c.pose.R[3 * r] * X[0] + c.pose.R[3 * r + 1] * X[1] + c.pose.R[3 * r + 2] * X[2] + c.pose.t[r];
  *z = p[2];
  *u = c.intr.fx * p[0] / p[2] + c.intr.cx;
  *v = c.intr.fy * p[1] / p[2] + c.intr.cy;
}

TEST_CASE("synth --object: RGBA images with exact coverage, subject inside every frame, masks repeat the alpha") {
  TempDir dir("hbgs_object");
  const ObjectOptions opt = small_object();
  auto summary = generate_object(opt, dir.path());
  REQUIRE_MESSAGE(summary.ok(), summary.status().to_string());
  CHECK(summary->num_views == 16);
  CHECK(summary->num_test_views == 2);
  CHECK(summary->num_points == 800);
  const int W = opt.width, H = opt.height;
  for (int v = 0; v < opt.views; ++v) {
    CAPTURE(v);
    char name[16];
    std::snprintf(name, sizeof name, "%04d.png", v);
    auto img = gs::io::read_image(dir / (std::string("images/") + name), gs::io::kChannelsAsStored);
    REQUIRE_MESSAGE(img.ok(), img.status().to_string());
    REQUIRE(img->channels == 4);
    auto mask = gs::io::read_image(dir / (std::string("masks/") + name), 1);
    REQUIRE(mask.ok());
    size_t opaque = 0, clear = 0, partial = 0, border_cover = 0, clear_but_coloured = 0;
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const size_t i = size_t(y) * W + size_t(x);
        const uint8_t a = img->pixels[4 * i + 3];
        CHECK(mask->pixels[i] == a);
        opaque += a == 255, clear += a == 0, partial += a > 0 && a < 255;
        if (a == 0) clear_but_coloured += img->pixels[4 * i] + img->pixels[4 * i + 1] + img->pixels[4 * i + 2] > 0;
        // The subject stays clear of a 2-pixel frame around the image.
        if (x < 2 || y < 2 || x >= W - 2 || y >= H - 2) border_cover += a > 0;
      }
    const double n = double(W) * H;
    CHECK(border_cover == 0);
    CHECK(clear_but_coloured == 0);
    CHECK(opaque / n > 0.15);   // the subject fills a good part of the frame
    CHECK(clear / n > 0.2);     // and the background is transparent
    CHECK(partial > 0);         // anti-aliased edges carry fractional coverage
    CHECK(partial / n < 0.15);  // only at the edges
  }
  // Deterministic, and independent of the thread count.
  TempDir again("hbgs_object_again");
  ObjectOptions one = opt;
  one.threads = 1;
  REQUIRE(generate_object(one, again.path()).ok());
  for (const char* f : {"images/0005.png", "masks/0005.png", "sparse/0/points3D.txt", "transforms_test.json"})
    CHECK_MESSAGE(slurp(dir / f) == slurp(again / f), f);
}

TEST_CASE("synth --object: the COLMAP and transforms.json versions load to the same views") {
  TempDir dir("hbgs_object_both");
  const ObjectOptions opt = small_object();
  REQUIRE(generate_object(opt, dir.path()).ok());
  const gs::io::Dataset colmap = load(dir.path(), DatasetLayout::kAuto);  // sparse/0 exists: COLMAP
  const gs::io::Dataset nerf = load(dir.path(), DatasetLayout::kTransforms);
  CHECK(colmap.layout == DatasetLayout::kColmap);
  CHECK(nerf.layout == DatasetLayout::kTransforms);
  REQUIRE(colmap.views.size() == 16);
  REQUIRE(nerf.views.size() == 16);
  for (size_t i = 0; i < 16; ++i) {
    const DatasetView& a = colmap.views[i];
    const DatasetView& b = nerf.views[i];
    CAPTURE(a.name);
    CHECK(b.name == "images/" + a.name);
    CHECK(a.is_test == (i % 8 == 0));
    CHECK(b.is_test == a.is_test);  // transforms_test.json holds COLMAP's every-8th views
    CHECK(b.camera.intr.width == a.camera.intr.width);
    CHECK(b.camera.intr.height == a.camera.intr.height);
    CHECK(b.camera.intr.fx == a.camera.intr.fx);
    CHECK(b.camera.intr.fy == a.camera.intr.fy);
    CHECK(b.camera.intr.cx == a.camera.intr.cx);
    CHECK(b.camera.intr.cy == a.camera.intr.cy);
    for (int k = 0; k < 9; ++k) CHECK(std::abs(b.camera.pose.R[k] - a.camera.pose.R[k]) < 1e-5);
    for (int k = 0; k < 3; ++k) CHECK(std::abs(b.camera.pose.t[k] - a.camera.pose.t[k]) < 1e-5);
    CHECK(b.image.pixels == a.image.pixels);
    REQUIRE_FALSE(a.mask.empty());
    CHECK(b.mask.pixels == a.mask.pixels);
  }
  CHECK(colmap.points_source == gs::io::PointsSource::kSfm);
  CHECK(colmap.points_xyz.size() == 3 * 800);
  CHECK(nerf.points_source == gs::io::PointsSource::kRandom);
  CHECK(nerf.points_xyz.size() == 3 * 10000);
  CHECK(nerf.random_min_view_fraction == 1.0);
  // Every random point is in every camera's view, and the box they fill holds the subject: the
  // surface points of the COLMAP version.
  for (size_t p = 0; p < nerf.points_xyz.size() / 3; p += 7) {
    const double X[3] = {nerf.points_xyz[3 * p], nerf.points_xyz[3 * p + 1], nerf.points_xyz[3 * p + 2]};
    for (const DatasetView& v : nerf.views) {
      double u, w, z;
      project(v.camera, X, &u, &w, &z);
      REQUIRE(z > 0.2);
      REQUIRE((u >= 0 && u < v.camera.intr.width && w >= 0 && w < v.camera.intr.height));
    }
  }
  size_t inside = 0;
  const size_t surface = colmap.points_xyz.size() / 3;
  for (size_t p = 0; p < surface; ++p) {
    bool in = true;
    for (int k = 0; k < 3; ++k)
      in = in && colmap.points_xyz[3 * p + size_t(k)] >= nerf.random_box_min[k] && colmap.points_xyz[3 * p + size_t(k)] <= nerf.random_box_max[k];
    inside += in;
  }
  MESSAGE("random points box [" << nerf.random_box_min[0] << ", " << nerf.random_box_max[0] << "] x [" << nerf.random_box_min[1]
                                << ", " << nerf.random_box_max[1] << "] x [" << nerf.random_box_min[2] << ", "
                                << nerf.random_box_max[2] << "]; " << inside << " of " << surface << " surface points inside");
  CHECK(inside == surface);
}

TEST_CASE("synth --object --object-background cluttered: RGB on a background, masks mark the subject") {
  TempDir dir("hbgs_object_clutter");
  ObjectOptions opt = small_object();
  opt.background = ObjectOptions::Background::kCluttered;
  REQUIRE(generate_object(opt, dir.path()).ok());
  CHECK(std::filesystem::exists(dir / "images/0000.jpg"));
  CHECK(std::filesystem::exists(dir / "masks/0000.jpg.png"));  // COLMAP's mask naming
  TempDir clear("hbgs_object_clear");
  REQUIRE(generate_object(small_object(), clear.path()).ok());
  const gs::io::Dataset colmap = load(dir.path(), DatasetLayout::kAuto);
  const gs::io::Dataset nerf = load(dir.path(), DatasetLayout::kTransforms);  // frames carry mask_path
  const gs::io::Dataset transparent = load(clear.path(), DatasetLayout::kAuto);
  REQUIRE(colmap.views.size() == 16);
  REQUIRE(nerf.views.size() == 16);
  for (size_t i = 0; i < 16; ++i) {
    const DatasetView& v = colmap.views[i];
    CAPTURE(v.name);
    REQUIRE(v.mask.pixels.size() == size_t(v.image.width) * v.image.height);
    CHECK(nerf.views[i].mask.pixels == v.mask.pixels);
    CHECK(nerf.views[i].image.pixels == v.image.pixels);
    // The same subject and cameras as the transparent capture: the same coverage.
    CHECK(v.mask.pixels == transparent.views[i].mask.pixels);
    for (int k = 0; k < 9; ++k) CHECK(v.camera.pose.R[k] == transparent.views[i].camera.pose.R[k]);
    // Where the mask is clear the image shows the background (ground, clutter, sky), not black; on
    // the subject it matches the transparent capture up to JPEG error.
    double background_level = 0, subject_error = 0;
    size_t nb = 0, ns = 0;
    for (size_t p = 0; p < v.mask.pixels.size(); ++p) {
      double sum = 0, err = 0;
      for (int c = 0; c < 3; ++c) {
        sum += v.image.pixels[3 * p + size_t(c)];
        err += std::abs(int(v.image.pixels[3 * p + size_t(c)]) - int(transparent.views[i].image.pixels[3 * p + size_t(c)]));
      }
      if (v.mask.pixels[p] == 0) background_level += sum / 3, ++nb;
      if (v.mask.pixels[p] == 255) subject_error += err / 3, ++ns;
    }
    REQUIRE(nb > 0);
    REQUIRE(ns > 0);
    CHECK(background_level / double(nb) > 40);
    CHECK(subject_error / double(ns) < 12);  // JPEG at quality 95 on textured 64x56 images
  }
}

TEST_CASE("synth --object: invalid options are refused") {
  TempDir dir("hbgs_object_bad");
  ObjectOptions o = small_object();
  o.views = 2;
  CHECK_FALSE(generate_object(o, dir.path()).ok());
  o = small_object();
  o.width = 200, o.height = 50;
  CHECK_FALSE(generate_object(o, dir.path()).ok());
  o = small_object();
  o.samples_per_axis = 0;
  CHECK_FALSE(generate_object(o, dir.path()).ok());
  CHECK(hbgs::synth::make_object_cameras(o).empty());
  CHECK(hbgs::synth::make_object_cameras(small_object()).size() == 16);
}

}  // namespace
