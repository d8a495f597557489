// SPDX-License-Identifier: MIT
// Run folders shared by train, eval, render and demo: locating the model and its dataset, the
// LPIPS weights, and merging evaluation results into the 3DGS results.json / per_view.json.
#include "model_run.h"

#include <cstdio>
#include <filesystem>
#include <system_error>

#include <nlohmann/json.hpp>

#include "gs/platform/file.h"

#ifndef HBGS_SOURCE_DIR
#define HBGS_SOURCE_DIR "."
#endif

namespace hbgs::cli {
namespace {

namespace fs = std::filesystem;

// Reads a JSON file; a missing file is an empty object when allow_missing.
gs::Expected<nlohmann::ordered_json> read_json(const std::string& path, bool allow_missing) {
  if (allow_missing && !gs::platform::file_exists(path)) return nlohmann::ordered_json::object();
  gs::Expected<std::string> text = gs::platform::read_text_file(path);
  if (!text.ok()) return text.status();
  nlohmann::ordered_json j = nlohmann::ordered_json::parse(*text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return gs::parse_error(path + ": not a JSON object");
  return j;
}

// Merges the single method object in `fresh` into the file at path (written atomically).
gs::Status merge_json_file(const std::string& path, const std::string& fresh) {
  gs::Expected<nlohmann::ordered_json> old = read_json(path, true);
  nlohmann::ordered_json merged = old.ok() ? *old : nlohmann::ordered_json::object();
  if (!old.ok()) std::fprintf(stderr, "note: replacing unreadable %s (%s)\n", path.c_str(), old.status().to_string().c_str());
  const nlohmann::ordered_json update = nlohmann::ordered_json::parse(fresh);
  for (auto it = update.begin(); it != update.end(); ++it) merged[it.key()] = it.value();
  return gs::platform::write_file_atomic(path, merged.dump(2) + "\n");
}

}  // namespace

std::string absolute_path(const std::string& path) {
  std::error_code ec;
  const fs::path p = fs::absolute(path, ec);
  return ec ? path : p.lexically_normal().string();
}

uint64_t file_size_or_zero(const std::string& path) {
  std::error_code ec;
  const uintmax_t n = fs::file_size(path, ec);
  return ec ? 0 : uint64_t(n);
}

bool is_model_input(const std::string& path) {
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_regular_file(p, ec)) return p.extension() == ".hbgs";
  return fs::is_directory(p, ec) && (fs::exists(p / kRunJson, ec) || fs::exists(p / kModelFile, ec));
}

gs::Expected<ModelSource> resolve_model_source(const std::string& path, const std::string& dataset_override,
                                               int max_width_override) {
  std::error_code ec;
  ModelSource s;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) {
    s.run_dir = path;
    s.model_path = (p / kModelFile).string();
    if (!gs::platform::file_exists(s.model_path))
      return gs::invalid_argument(path + " holds no " + kModelFile + " (the run has not finished; its " +
                                  kCheckpointFile + " can be continued with hbgs train --resume)");
  } else {
    s.model_path = path;
    s.run_dir = p.has_parent_path() ? p.parent_path().string() : std::string(".");
  }
  const std::string run_json = (fs::path(s.run_dir) / kRunJson).string();
  nlohmann::ordered_json run = nlohmann::ordered_json::object();
  if (gs::platform::file_exists(run_json)) {
    gs::Expected<nlohmann::ordered_json> j = read_json(run_json, false);
    if (!j.ok()) return j.status();
    run = std::move(j).value();
  }
  s.dataset = !dataset_override.empty() ? dataset_override : run.value("dataset", std::string());
  if (s.dataset.empty())
    return gs::invalid_argument("no dataset for " + path + ": no " + kRunJson + " next to it names one; pass --dataset DIR");
  s.max_width = max_width_override >= 0 ? max_width_override : run.value("max_width", 0);
  return s;
}

gs::Expected<std::unique_ptr<LoadedDataset>> load_dataset_split(const std::string& root, int max_width,
                                                                 const std::string& split) {
  if (!gs::platform::is_directory(root)) return gs::invalid_argument("dataset folder " + root + " not found");
  gs::io::DatasetOptions opt;
  opt.max_width = max_width;
  gs::Expected<gs::io::Dataset> ds = gs::io::load_dataset(root, opt);
  if (!ds.ok()) return ds.status();
  auto out = std::make_unique<LoadedDataset>();
  out->dataset = std::move(ds).value();
  for (const gs::io::DatasetView& v : out->dataset.views)
    if (split == "all" || (split == "test") == v.is_test) out->views.push_back(&v);
  if (out->views.empty()) return gs::invalid_argument(root + ": no views in split '" + split + "'");
  return out;
}

std::string default_lpips_dir() {
  const fs::path dir = fs::path(HBGS_SOURCE_DIR) / ".." / "shared" / "data" / "lpips_alex";
  std::error_code ec;
  return fs::exists(dir / "weights.bin", ec) ? dir.lexically_normal().string() : std::string();
}

gs::Expected<std::unique_ptr<gs::metrics::LpipsAlex>> load_lpips(const std::string& explicit_dir, int threads,
                                                                bool quiet) {
  const std::string dir = explicit_dir.empty() ? default_lpips_dir() : explicit_dir;
  if (dir.empty()) {
    if (!quiet)
      std::fprintf(stderr, "note: no LPIPS weights (../shared/data/lpips_alex is absent; pass --lpips-weights DIR); "
                           "LPIPS is not computed\n");
    return std::unique_ptr<gs::metrics::LpipsAlex>();
  }
  gs::Expected<gs::metrics::LpipsAlex> net = gs::metrics::LpipsAlex::load(dir, threads);
  if (!net.ok()) return gs::Status(net.status().code(), "LPIPS weights: " + net.status().message());
  return std::make_unique<gs::metrics::LpipsAlex>(std::move(net).value());
}

std::string json_members(const std::string& object_dump) {
  if (object_dump.size() < 2) return "";
  return object_dump.substr(1, object_dump.size() - 2);
}

gs::Status write_eval_files(const std::string& dir, const std::string& method, const gs::model::EvalResult& r,
                            const std::string& extra_members) {
  GS_RETURN_IF_ERROR(gs::platform::make_dirs(dir));
  GS_RETURN_IF_ERROR(merge_json_file((fs::path(dir) / kResultsJson).string(),
                                     gs::model::results_json(r, method, extra_members)));
  return merge_json_file((fs::path(dir) / kPerViewJson).string(), gs::model::per_view_json(r, method));
}

}  // namespace hbgs::cli
