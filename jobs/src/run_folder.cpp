// SPDX-License-Identifier: MIT
// Run folders shared by the jobs: locating the model and its dataset, the LPIPS weights, and
// merging evaluation results into the 3DGS results.json / per_view.json.
#include "gs/jobs/run_folder.h"

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include <nlohmann/json.hpp>

#include "gs/io/splat_formats.h"
#include "gs/model/compact_model.h"
#include "gs/model/trainer.h"
#include "gs/platform/file.h"
#include "gs/platform/path.h"
#include "json_util.h"

namespace gs::jobs {
namespace {

namespace fs = std::filesystem;

// Reads a JSON file; a missing file is an empty object when allow_missing.
Expected<nlohmann::ordered_json> read_json(const std::string& path, bool allow_missing) {
  if (allow_missing && !platform::file_exists(path)) return nlohmann::ordered_json::object();
  Expected<std::string> text = platform::read_text_file(path);
  if (!text.ok()) return text.status();
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(*text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return parse_error(path + ": not a JSON object");
  return j;
}

// Sets `method` to `object` in the JSON file at path, keeping its other members (written
// atomically; an unreadable file is replaced and *note says so).
Status merge_json_file(const std::string& path, const std::string& method, nlohmann::ordered_json object, std::string* note) {
  Expected<nlohmann::ordered_json> old = read_json(path, true);
  nlohmann::ordered_json merged = old.ok() ? *old : nlohmann::ordered_json::object();
  if (!old.ok() && note) *note += "replacing unreadable " + path + " (" + old.status().to_string() + ")\n";
  merged[method] = std::move(object);
  return platform::write_file_atomic(path, merged.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace) + "\n");
}

// results.json's method object in the 3DGS schema: "SSIM", "PSNR", "LPIPS" (when computed), with
// masks "PSNR_masked", "alpha_MAE" and "alpha_IoU", then the members of extra. Non-finite numbers
// are written as null (JSON has no Inf / NaN).
nlohmann::ordered_json results_object(const model::EvalResult& r, const nlohmann::json& extra) {
  nlohmann::ordered_json o = nlohmann::ordered_json::object();
  o["SSIM"] = r.ssim;
  o["PSNR"] = r.psnr;
  if (r.lpips >= 0) o["LPIPS"] = r.lpips;
  if (r.psnr_masked >= 0) {
    o["PSNR_masked"] = r.psnr_masked;
    o["alpha_MAE"] = r.alpha_mae;
    o["alpha_IoU"] = r.alpha_iou;
  }
  for (auto it = extra.begin(); it != extra.end(); ++it) o[it.key()] = it.value();
  return o;
}

// per_view.json's method object: the same metrics, each an object of view name -> value.
nlohmann::ordered_json per_view_object(const model::EvalResult& r) {
  auto metric = [&r](double model::ViewMetrics::*field) {
    nlohmann::ordered_json m = nlohmann::ordered_json::object();
    for (const model::ViewMetrics& v : r.views) m[v.name] = v.*field;
    return m;
  };
  nlohmann::ordered_json o = nlohmann::ordered_json::object();
  o["SSIM"] = metric(&model::ViewMetrics::ssim);
  o["PSNR"] = metric(&model::ViewMetrics::psnr);
  if (r.lpips >= 0) o["LPIPS"] = metric(&model::ViewMetrics::lpips);
  if (r.psnr_masked >= 0) {
    o["PSNR_masked"] = metric(&model::ViewMetrics::psnr_masked);
    o["alpha_MAE"] = metric(&model::ViewMetrics::alpha_mae);
    o["alpha_IoU"] = metric(&model::ViewMetrics::alpha_iou);
  }
  return o;
}

}  // namespace

std::string absolute_path(const std::string& path) {
  std::error_code ec;
  const fs::path p = fs::absolute(path, ec);
  return ec ? path : p.lexically_normal().string();
}

namespace {

bool is_json_file(const std::string& path) {
  std::error_code ec;
  const fs::path p(path);
  return p.extension() == ".json" && fs::is_regular_file(p, ec);
}

}  // namespace

Status check_dataset_path(const std::string& dataset) {
  if (platform::is_directory(dataset) || is_json_file(dataset)) return Status::Ok();
  const std::string forms = "give a dataset folder (COLMAP, or NeRF-style with transforms.json) or a NeRF-style transforms .json file";
  if (!platform::file_exists(dataset)) return invalid_argument("dataset " + dataset + " not found: " + forms);
  return invalid_argument("dataset " + dataset + " is neither a folder nor a .json file: " + forms);
}

std::string dataset_folder(const std::string& dataset) {
  if (!is_json_file(dataset)) return dataset;
  const fs::path p(dataset);
  return p.has_parent_path() ? p.parent_path().string() : std::string(".");
}

Status check_output_outside_dataset(const std::string& out, const std::string& dataset) {
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec)) return invalid_argument("output " + out + " exists and is not a directory");
  const std::string folder = dataset_folder(dataset);
  if (!platform::path_is_inside(out, folder)) return Status::Ok();
  // Inside the dataset: a sub-folder of its own ("DATASET/renders") is fine; the dataset folder
  // itself, its images (images/, images_2/ ...) and its model (sparse/) are not.
  const fs::path ds = fs::weakly_canonical(fs::absolute(folder, ec), ec);
  const fs::path rel = fs::weakly_canonical(fs::absolute(out, ec), ec).lexically_relative(ds);
  const std::string first = rel.empty() ? std::string(".") : rel.begin()->string();
  if (first == "." || first.rfind("images", 0) == 0 || first == "sparse")
    return invalid_argument("output " + out + (first == "." ? " is the dataset folder " + folder : " is inside the dataset's " + first + "/ folder") +
                            ": writing there would change the dataset; choose another --out");
  return Status::Ok();
}

uint64_t file_size_or_zero(const std::string& path) {
  std::error_code ec;
  const uintmax_t n = fs::file_size(path, ec);
  return ec ? 0 : uint64_t(n);
}

bool is_splat_file(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec) && io::splat_format_from_extension(path).ok();
}

bool is_model_input(const std::string& path) {
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_regular_file(p, ec)) {
    if (p.extension() == ".hbgs" || p.extension() == ".hbgc" || is_splat_file(path)) return true;
    // Any model file by its magic: float "HBGSMODL" or compact "HBGSCMPT".
    uint8_t head[8] = {};
    std::ifstream f(p, std::ios::binary);
    if (!f.read(reinterpret_cast<char*>(head), 8)) return false;
    return std::memcmp(head, "HBGSMODL", 8) == 0 || model::is_compact_file(head, 8);
  }
  return fs::is_directory(p, ec) && (fs::exists(p / kRunJson, ec) || fs::exists(p / kModelFile, ec));
}

Expected<ModelSource> resolve_model_source(const std::string& path, const std::string& dataset_override,
                                               int max_width_override) {
  std::error_code ec;
  ModelSource s;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) {
    s.run_dir = path;
    s.model_path = (p / kModelFile).string();
    if (!platform::file_exists(s.model_path))
      return invalid_argument(path + " holds no " + kModelFile + " (the run has not finished; its " +
                                  kCheckpointFile + " can be continued with hbgs train --resume)");
  } else {
    s.model_path = path;
    s.run_dir = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  }
  const std::string run_json = (fs::path(s.run_dir) / kRunJson).string();
  nlohmann::ordered_json run = nlohmann::ordered_json::object();
  if (platform::file_exists(run_json)) {
    Expected<nlohmann::ordered_json> j = read_json(run_json, false);
    if (!j.ok()) return j.status();
    run = std::move(j).value();
  }
  s.dataset = !dataset_override.empty() ? dataset_override : run.value("dataset", std::string());
  if (s.dataset.empty())
    return invalid_argument("no dataset for " + path + ": no " + kRunJson + " next to it names one; pass --dataset DIR");
  s.max_width = max_width_override >= 0 ? max_width_override : run.value("max_width", 0);
  if (run.contains("fisheye_fov")) {
    if (!run["fisheye_fov"].is_number()) return parse_error(run_json + ": fisheye_fov is not a number");
    s.fisheye_fov = run["fisheye_fov"].get<double>();
  }
  if (run.contains("options") && run["options"].is_object() && run["options"].contains("background")) {
    if (!run["options"]["background"].is_string()) return parse_error(run_json + ": options.background is not a string");
    s.background = run["options"]["background"].get<std::string>();
  }
  return s;
}

Expected<model::Background> model_background(const ModelSource& source, const std::string& override_text) {
  const std::string& text = override_text.empty() ? source.background : override_text;
  Expected<model::Background> b = model::parse_background(text);
  if (!b.ok())
    return Status(b.status().code(), (override_text.empty() ? source.run_dir + "/" + kRunJson + ": " : std::string("--background: ")) +
                                         b.status().message());
  return b;
}

Expected<std::unique_ptr<LoadedDataset>> load_dataset_split(const std::string& root, int max_width,
                                                                 const std::string& split, const SceneFrame* frame,
                                                                 double fisheye_fov) {
  GS_RETURN_IF_ERROR(check_dataset_path(root));
  io::DatasetOptions opt;
  opt.max_width = max_width;
  opt.fisheye_fov_deg = fisheye_fov;
  if (frame) opt.frame = *frame;
  if (split == "test") opt.images = io::DatasetOptions::Images::kTest;
  if (split == "train") opt.images = io::DatasetOptions::Images::kTrain;
  Expected<io::Dataset> ds = io::load_dataset(root, opt);
  if (!ds.ok()) return ds.status();
  auto out = std::make_unique<LoadedDataset>();
  out->dataset = std::move(ds).value();
  for (const io::DatasetView& v : out->dataset.views)
    if (split == "all" || (split == "test") == v.is_test) out->views.push_back(&v);
  if (out->views.empty()) return invalid_argument(root + ": no views in split '" + split + "'");
  return out;
}

Expected<ModelViews> load_model_views(const std::string& input, const std::string& dataset_override, int max_width_override,
                                      const std::string& split, double fisheye_fov_override) {
  ModelViews out;
  Expected<ModelSource> src = resolve_model_source(input, dataset_override, max_width_override);
  if (!src.ok()) return src.status();
  out.source = std::move(src).value();
  if (fisheye_fov_override >= 0) out.source.fisheye_fov = fisheye_fov_override;
  if (is_splat_file(out.source.model_path)) {
    Expected<GaussianCloud> cloud = io::read_gaussians(out.source.model_path);
    if (!cloud.ok()) return cloud.status();
    if (cloud->size() == 0) return invalid_argument(out.source.model_path + ": holds no Gaussians");
    out.cloud = std::make_unique<GaussianCloud>(std::move(cloud).value());
  } else {
    Expected<model::HybridModel> model = model::load_model(out.source.model_path, &out.compact);
    if (!model.ok()) return model.status();
    out.model = std::move(model).value();
  }
  // The dataset goes into the model's scene frame; plain Gaussians (in the user's frame, as every
  // splat file is) go into the dataset's.
  Expected<std::unique_ptr<LoadedDataset>> data =
      load_dataset_split(out.source.dataset, out.source.max_width, split, out.cloud ? nullptr : &out.model.frame,
                         out.source.fisheye_fov);
  if (!data.ok()) return data.status();
  out.data = std::move(data).value();
  if (out.cloud) cloud_to_frame(out.data->dataset.frame, out.cloud.get());
  return out;
}

Expected<model::EvalResult> evaluate_loaded(const ModelViews& loaded, const std::vector<const io::DatasetView*>& views,
                                            const model::EvalOptions& options, platform::ThreadPool* pool) {
  if (loaded.cloud) return model::evaluate_views(*loaded.cloud, views, options, pool);
  return model::evaluate_views(loaded.model, views, options, pool);
}

float ModelViews::scene_extent() const {
  if (!cloud) return model.scene_extent;
  std::vector<const Camera*> train;
  for (const io::DatasetView& v : data->dataset.views)
    if (!v.is_test) train.push_back(&v.camera);
  if (train.empty())
    for (const io::DatasetView& v : data->dataset.views) train.push_back(&v.camera);
  return model::cameras_extent(train);
}

std::string default_lpips_dir() {
  std::error_code ec;
  auto holds = [&](const fs::path& dir) { return fs::exists(dir / "weights.bin", ec); };
  if (const char* env = std::getenv("HBGS_LPIPS_WEIGHTS"); env && *env) return holds(env) ? std::string(env) : std::string();
  std::vector<fs::path> bases = {fs::current_path(ec)};
  for (fs::path p = fs::path(platform::executable_path()).parent_path(); !p.empty() && p != p.root_path(); p = p.parent_path())
    bases.push_back(p);
  for (const fs::path& base : bases) {
    const fs::path dir = base.parent_path() / "shared" / "data" / "lpips_alex";
    if (!base.empty() && holds(dir)) return dir.lexically_normal().string();
  }
  return std::string();
}

Expected<std::unique_ptr<metrics::LpipsAlex>> load_lpips(const std::string& explicit_dir, int threads, std::string* note) {
  const std::string dir = explicit_dir.empty() ? default_lpips_dir() : explicit_dir;
  if (dir.empty()) {
    if (note)
      *note = "no LPIPS weights (no ../shared/data/lpips_alex and HBGS_LPIPS_WEIGHTS is unset; pass --lpips-weights DIR); "
              "LPIPS is not computed";
    return std::unique_ptr<metrics::LpipsAlex>();
  }
  Expected<metrics::LpipsAlex> net = metrics::LpipsAlex::load(dir, threads);
  if (!net.ok()) return Status(net.status().code(), "LPIPS weights: " + net.status().message());
  return std::make_unique<metrics::LpipsAlex>(std::move(net).value());
}

Status write_eval_files(const std::string& dir, const std::string& method, const model::EvalResult& r,
                        const nlohmann::json& extra, std::string* note) {
  GS_RETURN_IF_ERROR(platform::make_dirs(dir));
  GS_RETURN_IF_ERROR(merge_json_file((fs::path(dir) / kResultsJson).string(), method, results_object(r, extra), note));
  return merge_json_file((fs::path(dir) / kPerViewJson).string(), method, per_view_object(r), note);
}

}  // namespace gs::jobs
