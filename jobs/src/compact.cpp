// SPDX-License-Identifier: MIT
// The compact job (gs/jobs/compact.h).
#include "gs/jobs/compact.h"

#include <algorithm>

#include <vector>

#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/platform/thread_pool.h"

namespace gs::jobs {

Status compact_run(const CompactRunOptions& a, CompactRunSummary* summary) {
  if (a.out.empty()) return invalid_argument("--out: the compact model file to write is required");
  if (!platform::file_exists(a.input)) return invalid_argument(a.input + " not found");
  if (!is_model_input(a.input))
    return invalid_argument(a.input + " is neither a run folder (with run.json or model.hbgs) nor a model file");
  if (is_splat_file(a.input))
    return invalid_argument(a.input + " holds plain Gaussians; compact files hold anchor models (hbgs train, then hbgs compact RUN)");
  const double t0 = platform::now_seconds();
  Expected<ModelViews> loaded = load_model_views(a.input, a.dataset, a.max_width, "all");
  if (!loaded.ok()) return loaded.status();
  CompactRunSummary s;
  s.source = loaded->source;
  if (absolute_path(a.out) == absolute_path(s.source.model_path))
    return invalid_argument("--out " + a.out + " is the input model; choose another file");
  std::vector<Camera> train;
  std::vector<const io::DatasetView*> test;
  for (const io::DatasetView* v : loaded->data->views) {
    if (v->is_test) test.push_back(v);
    else train.push_back(v->camera);
  }
  if (train.empty()) return invalid_argument(s.source.dataset + ": no training views to calibrate on");
  platform::ThreadPool pool(a.threads);
  Expected<model::CompactModel> cm = model::compact_from_model(loaded->model, train, a.compact, &pool, &s.stats);
  if (!cm.ok()) return cm.status();
  GS_RETURN_IF_ERROR(model::save_compact(*cm, a.out));
  s.float_bytes = file_size_or_zero(s.source.model_path);
  s.compact_bytes = file_size_or_zero(a.out);
  if (a.evaluate && !test.empty()) {
    // The compact model as every loader sees it: read back from the file just written.
    Expected<model::HybridModel> back = model::load_model(a.out);
    if (!back.ok()) return back.status();
    Expected<model::Background> background = model_background(s.source, "");
    if (!background.ok()) return background.status();
    model::EvalOptions eo;
    eo.psnr_only = true;
    std::copy(background->rgb, background->rgb + 3, eo.render.background);
    Expected<model::EvalResult> fe = model::evaluate_views(loaded->model, test, eo, &pool);
    if (!fe.ok()) return fe.status();
    Expected<model::EvalResult> ce = model::evaluate_views(*back, test, eo, &pool);
    if (!ce.ok()) return ce.status();
    s.float_eval = std::move(fe).value();
    s.compact_eval = std::move(ce).value();
    s.evaluated = true;
  }
  s.seconds = platform::now_seconds() - t0;
  if (summary) *summary = std::move(s);
  return Status::Ok();
}

}  // namespace gs::jobs
