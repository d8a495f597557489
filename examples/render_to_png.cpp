// SPDX-License-Identifier: MIT
// Example: render one camera of a dataset (COLMAP or NeRF-style) to a PNG, from a trained hbgs
// model (.hbgs, or the compact .hbgc), a splat file of any format hbgs reads (3DGS .ply,
// .compressed.ply, .splat, .spz: gs::io::read_gaussians), or the dataset's own points as small
// Gaussians ("points"). Built only against the installed hbgs (find_package(hbgs) -> hbgs::hbgs,
// or pkg-config hbgs).
//   render_to_png DATASET MODEL.hbgs|MODEL.hbgc|SPLATS.{ply,compressed.ply,splat,spz}|points OUT.png [VIEW] [MAX_WIDTH]
// VIEW is an image name of the dataset or an index into its views sorted by name (default 0);
// MAX_WIDTH > 0 downscales the camera (and the image compared against) to at most that width.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "gs/io/colmap.h"             // gs::io::load_dataset: pinhole cameras, images, SfM points
#include "gs/io/image.h"              // gs::io::image_from_float_rgb, write_png
#include "gs/io/splat_formats.h"      // gs::io::read_gaussians (any splat format)
#include "gs/metrics/image_metrics.h"  // gs::metrics::psnr_u8
#include "gs/model/hybrid_model.h"    // gs::model::load_model
#include "gs/model/model_renderer.h"  // gs::model::ModelRenderer
#include "gs/platform/thread_pool.h"  // gs::platform::ThreadPool
#include "gs/render.h"                // gs::Renderer
#include "gs/scene_init.h"            // gs::gaussians_from_points, gs::activate

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

int fail(const std::string& what, const gs::Status& st) {
  std::fprintf(stderr, "render_to_png: %s: %s\n", what.c_str(), st.to_string().c_str());
  return 1;
}

// PSNR of the render against the photo (+inf when identical, NaN when the sizes differ).
double psnr(const gs::io::Image8& a, const gs::io::Image8& b) {
  if (a.pixels.size() != b.pixels.size()) return NAN;
  return gs::metrics::psnr_u8(a.pixels.data(), b.pixels.data(), a.pixels.size());
}

// Renders a Gaussian cloud (a splat file or the dataset's points) with the differentiable
// renderer, forward only.
gs::Status render_cloud(const gs::GaussianCloud& cloud, const gs::Camera& camera, gs::platform::ThreadPool* pool,
                        float* rgb) {
  std::vector<float> opacities;
  const gs::GaussianParams params = gs::activate(cloud, &opacities);
  gs::RenderCapacity capacity;  // plan: the arena is allocated once in init()
  capacity.max_gaussians = cloud.size();
  capacity.max_width = camera.intr.width;
  capacity.max_height = camera.intr.height;
  capacity.max_sh_degree = cloud.sh_degree;
  gs::Renderer renderer;
  for (;;) {
    if (gs::Status st = renderer.init(capacity, pool); !st.ok()) return st;
    gs::Status st = renderer.forward(camera, params, gs::RenderOptions{}, rgb);
    if (st.code() != gs::StatusCode::kCapacityExceeded) return st;
    // More Gaussian-tile pairs than planned: plan for what this view needs and render again.
    capacity.max_isects = std::max(renderer.stats().isects, 2 * std::max<size_t>(capacity.max_isects, 16 * cloud.size()));
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: %s DATASET MODEL.hbgs|MODEL.hbgc|SPLATS.{ply,compressed.ply,splat,spz}|points OUT.png [VIEW] [MAX_WIDTH]\n",
                 argv[0]);
    return 2;
  }
  const std::string dataset_dir = argv[1], source = argv[2], out = argv[3];
  const std::string view_arg = argc > 4 ? argv[4] : "0";
  gs::io::DatasetOptions options;
  options.max_width = argc > 5 ? std::atoi(argv[5]) : 0;

  gs::Expected<gs::io::Dataset> dataset = gs::io::load_dataset(dataset_dir, options);
  if (!dataset.ok()) return fail(dataset_dir, dataset.status());
  const gs::io::DatasetView* view = nullptr;
  for (const gs::io::DatasetView& v : dataset->views)
    if (v.name == view_arg) view = &v;
  if (!view && !view_arg.empty() && view_arg.find_first_not_of("0123456789") == std::string::npos &&
      std::stoul(view_arg) < dataset->views.size())
    view = &dataset->views[std::stoul(view_arg)];
  if (!view) {
    std::fprintf(stderr, "render_to_png: %s has no view '%s' (%zu views)\n", dataset_dir.c_str(), view_arg.c_str(),
                 dataset->views.size());
    return 1;
  }
  const gs::Camera& camera = view->camera;
  const int w = camera.intr.width, h = camera.intr.height;

  gs::platform::ThreadPool pool(0);  // all CPUs
  std::vector<float> rgb(size_t(w) * size_t(h) * 3);
  const auto t0 = std::chrono::steady_clock::now();
  if (ends_with(source, ".hbgs") || ends_with(source, ".hbgc")) {
    gs::Expected<gs::model::HybridModel> model = gs::model::load_model(source);  // either kind, by its magic
    if (!model.ok()) return fail(source, model.status());
    gs::model::ModelRenderer renderer;
    if (gs::Status st = renderer.init(*model, w, h, &pool); !st.ok()) return fail("renderer", st);
    if (gs::Status st = renderer.render(*model, camera, rgb.data()); !st.ok()) return fail(view->name, st);
  } else {
    gs::GaussianCloud cloud;
    if (source == "points") {
      cloud = gs::gaussians_from_points(dataset->points_xyz.data(), dataset->points_rgb.data(),
                                        dataset->points_xyz.size() / 3);
    } else {
      gs::io::SplatFormat format;
      gs::Expected<gs::GaussianCloud> splats = gs::io::read_gaussians(source, &format);
      if (!splats.ok()) return fail(source, splats.status());
      std::printf("%s: %s, %zu Gaussians, SH degree %d\n", source.c_str(), gs::io::splat_format_name(format), splats->size(),
                  splats->sh_degree);
      cloud = std::move(splats).value();
      gs::cloud_to_frame(dataset->frame, &cloud);  // splat files are in the user's frame, the cameras in the scene frame
    }
    if (cloud.size() == 0) {
      std::fprintf(stderr, "render_to_png: %s: no Gaussians\n", source.c_str());
      return 1;
    }
    if (gs::Status st = render_cloud(cloud, camera, &pool, rgb.data()); !st.ok()) return fail(view->name, st);
  }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  const gs::io::Image8 image = gs::io::image_from_float_rgb(rgb.data(), w, h);
  if (gs::Status st = gs::io::write_png(out, image); !st.ok()) return fail(out, st);
  std::printf("%s: view %s (%dx%d) rendered in %.1f ms, PSNR %.2f dB against the photo -> %s\n", source.c_str(),
              view->name.c_str(), w, h, ms, psnr(image, view->image), out.c_str());
  return 0;
}
