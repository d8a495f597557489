// SPDX-License-Identifier: MIT
// The export job (gs/jobs/export.h).
#include "gs/jobs/export.h"

#include <algorithm>
#include <vector>

#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"

namespace gs::jobs {

Status check_bake_input(const std::string& input) {
  if (!platform::file_exists(input)) return invalid_argument(input + " not found");
  if (is_splat_file(input)) return invalid_argument(input + " already holds plain Gaussians; only anchor models are baked");
  if (!is_model_input(input))
    return invalid_argument(input + " is neither a run folder (with run.json or model.hbgs) nor a model file (.hbgs, .hbgc)");
  return Status::Ok();
}

Expected<GaussianCloud> bake_over_training_views(const ModelViews& loaded, const model::Background& background,
                                                 model::BakeOptions options, platform::ThreadPool* pool,
                                                 model::BakeStats* stats) {
  std::vector<Camera> train;
  for (const io::DatasetView& v : loaded.data->dataset.views)
    if (!v.is_test) train.push_back(v.camera);
  if (train.empty()) return invalid_argument(loaded.source.dataset + ": no training views to bake over");
  std::copy(background.rgb, background.rgb + 3, options.background);
  return model::bake_model(loaded.model, train, options, pool, stats);
}

namespace {

// Test PSNR (8-bit) of the input (a model or plain Gaussians) and of the file just written, read back
// as every reader sees it (so the format's quantisation counts).
template <class Input>
Status measure_written(const Input& input, const std::string& written, const std::vector<const io::DatasetView*>& test,
                       const SceneFrame& frame, const model::Background& background, platform::ThreadPool* pool,
                       ExportRunSummary* s) {
  if (test.empty()) return Status::Ok();
  Expected<GaussianCloud> back = io::read_gaussians(written);
  if (!back.ok()) return back.status();
  cloud_to_frame(frame, &*back);  // written in the user's frame; the test views are in the scene frame
  model::EvalOptions eo;
  eo.psnr_only = true;
  std::copy(background.rgb, background.rgb + 3, eo.render.background);
  Expected<model::EvalResult> me = model::evaluate_views(input, test, eo, pool);
  if (!me.ok()) return me.status();
  Expected<model::EvalResult> be = model::evaluate_views(*back, test, eo, pool);
  if (!be.ok()) return be.status();
  s->model_eval = std::move(me).value();
  s->baked_eval = std::move(be).value();
  s->evaluated = true;
  return Status::Ok();
}

std::vector<const io::DatasetView*> test_views(const ModelViews& loaded) {
  std::vector<const io::DatasetView*> test;
  for (const io::DatasetView& v : loaded.data->dataset.views)
    if (v.is_test) test.push_back(&v);
  return test;
}

// A splat file to another format, as it is; measured when a dataset is known (given, or named by a
// run.json beside the file) and evaluation is asked for.
Status convert(const ExportRunOptions& a, io::SplatFormat format, double t0, ExportRunSummary* summary) {
  if (absolute_path(a.out) == absolute_path(a.input)) return invalid_argument("--out " + a.out + " is the input file");
  ExportRunSummary s;
  s.format = format;
  s.source.model_path = a.input;
  const bool measure = a.evaluate && resolve_model_source(a.input, a.dataset, a.max_width).ok();
  Expected<ModelViews> loaded = measure ? load_model_views(a.input, a.dataset, a.max_width, "test") : Expected<ModelViews>(ModelViews{});
  if (!loaded.ok()) return loaded.status();
  if (measure) s.source = loaded->source;
  // The file as read (the user's frame; load_model_views moved its copy into the scene frame).
  Expected<GaussianCloud> c = io::read_gaussians(a.input);
  if (!c.ok()) return c.status();
  GS_RETURN_IF_ERROR(io::write_gaussians(a.out, *c, a.write));
  s.gaussians = c->size();
  s.bytes = file_size_or_zero(a.out);
  if (measure) {
    Expected<model::Background> background = model_background(s.source, "");
    if (!background.ok()) return background.status();
    platform::ThreadPool pool(a.threads);
    GS_RETURN_IF_ERROR(measure_written(*loaded->cloud, a.out, test_views(*loaded), loaded->frame(), *background, &pool, &s));
  }
  s.seconds = platform::now_seconds() - t0;
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

}  // namespace

Status export_run(const ExportRunOptions& a, ExportRunSummary* summary) {
  if (a.out.empty()) return invalid_argument("--out: the file to write is required (its extension picks the format: " +
                                             std::string(io::supported_splat_extensions()) + ")");
  Expected<io::SplatFormat> format = io::splat_format_from_extension(a.out);
  if (!format.ok()) return Status(format.status().code(), "--out: " + format.status().message());
  if (a.sh_degree < 0 || a.sh_degree > 3) return invalid_argument("--sh-degree must be 0-3");
  if (a.distill_iterations < 0) return invalid_argument("--distill must be 0 or more");
  if (*format == io::SplatFormat::kSpz) {  // the version and this build's codecs, before a long bake
    Expected<std::vector<uint8_t>> empty = io::encode_spz(GaussianCloud{}, a.write.spz);
    if (!empty.ok()) return Status(empty.status().code(), "--out " + a.out + ": " + empty.status().message());
  }
  const double t0 = platform::now_seconds();
  if (platform::file_exists(a.input) && is_splat_file(a.input)) return convert(a, *format, t0, summary);
  GS_RETURN_IF_ERROR(check_bake_input(a.input));
  // The cameras of every view and the test views' images (the training images are not needed).
  Expected<ModelViews> loaded = load_model_views(a.input, a.dataset, a.max_width, "test");
  if (!loaded.ok()) return loaded.status();
  ExportRunSummary s;
  s.source = loaded->source;
  s.format = *format;
  if (absolute_path(a.out) == absolute_path(s.source.model_path)) return invalid_argument("--out " + a.out + " is the input model");
  Expected<model::Background> background = model_background(s.source, "");
  if (!background.ok()) return background.status();
  platform::ThreadPool pool(a.threads);
  model::BakeOptions bo;
  bo.sh_degree = *format == io::SplatFormat::kAntimatterSplat ? 0 : a.sh_degree;  // .splat stores colour only
  bo.distill_iterations = a.distill_iterations;
  bo.seed = a.seed;
  Expected<GaussianCloud> cloud = bake_over_training_views(*loaded, *background, bo, &pool, &s.bake);
  if (!cloud.ok()) return cloud.status();
  cloud_to_user(loaded->frame(), &*cloud);  // files are in the user's frame (the dataset's own)
  GS_RETURN_IF_ERROR(io::write_gaussians(a.out, *cloud, a.write));
  s.gaussians = cloud->size();
  s.bytes = file_size_or_zero(a.out);
  if (a.evaluate) GS_RETURN_IF_ERROR(measure_written(loaded->model, a.out, test_views(*loaded), loaded->frame(), *background, &pool, &s));
  s.seconds = platform::now_seconds() - t0;
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

}  // namespace gs::jobs
