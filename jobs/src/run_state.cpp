// SPDX-License-Identifier: MIT
// Run folder commits (gs/jobs/run_state.h): ".next" files, manifest.json as the commit point, renames,
// and the recovery that completes or discards an interrupted commit.
#include "gs/jobs/run_state.h"

#include <cinttypes>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <system_error>

#include <nlohmann/json.hpp>

#include "gs/hash.h"

namespace gs::jobs {
namespace {

namespace fs = std::filesystem;

std::string hex64(uint64_t v) {
  char buf[20];
  std::snprintf(buf, sizeof(buf), "%016" PRIx64, v);
  return buf;
}

// Size and checksum of a file; error when it cannot be read.
Expected<RunStateFile> describe(const std::string& path, const std::string& name) {
  Expected<std::vector<uint8_t>> bytes = platform::read_file(path);
  if (!bytes.ok()) return bytes.status();
  RunStateFile f;
  f.name = name;
  f.bytes = bytes->size();
  f.fnv1a64 = fnv1a64(bytes->data(), bytes->size());
  return f;
}

bool matches(const std::string& path, const RunStateFile& want) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec) || fs::file_size(path, ec) != want.bytes) return false;
  Expected<RunStateFile> got = describe(path, want.name);
  return got.ok() && got->fnv1a64 == want.fnv1a64;
}

// A name the manifest may list: a plain file name inside the run folder, never a path.
bool plain_name(const std::string& n) {
  return !n.empty() && n != "." && n != ".." && n.find('/') == std::string::npos && n.find('\0') == std::string::npos;
}

Expected<RunState> read_manifest(const std::string& run) {
  RunState st;
  const std::string path = (fs::path(run) / kManifestFile).string();
  if (!platform::file_exists(path)) return st;
  Expected<std::string> text = platform::read_text_file(path, uint64_t(1) << 20);
  if (!text.ok()) return text.status();
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, false);
  auto bad = [&](const std::string& why) { return parse_error(path + ": " + why + " (the run folder's state cannot be trusted; start over with --force)"); };
  if (!j.is_object() || j.value("format", std::string()) != "hbgs-run-manifest") return bad("not an hbgs run manifest");
  if (j.value("version", 0) != 1) return bad("manifest version " + j.value("version", nlohmann::json()).dump() + ", this hbgs reads version 1");
  if (!j.contains("iteration") || !j["iteration"].is_number_integer() || j["iteration"].get<int64_t>() < 0 ||
      j["iteration"].get<int64_t>() > 1000000000)
    return bad("no valid \"iteration\"");
  if (!j.contains("files") || !j["files"].is_object() || j["files"].empty()) return bad("no \"files\"");
  st.committed = true;
  st.iteration = j["iteration"].get<int>();
  st.dataset = j.value("dataset", std::string());
  st.model_options = j.contains("model_options") ? j["model_options"].dump() : std::string("{}");
  for (auto it = j["files"].begin(); it != j["files"].end(); ++it) {
    const nlohmann::json& f = it.value();
    if (!plain_name(it.key())) return bad("file name '" + it.key() + "' is not a plain name inside the run folder");
    if (!f.is_object() || !f.contains("bytes") || !f["bytes"].is_number_unsigned() || !f.contains("fnv1a64") ||
        !f["fnv1a64"].is_string())
      return bad("entry for " + it.key() + " lacks \"bytes\" or \"fnv1a64\"");
    RunStateFile e;
    e.name = it.key();
    e.bytes = f["bytes"].get<uint64_t>();
    const std::string h = f["fnv1a64"].get<std::string>();
    char* end = nullptr;
    e.fnv1a64 = std::strtoull(h.c_str(), &end, 16);
    if (h.size() != 16 || end != h.c_str() + h.size()) return bad("checksum of " + it.key() + " is not 16 hex digits");
    st.files.push_back(e);
  }
  return st;
}

// Leftovers a failed or killed writer can leave: "<name>.next" and "<name>.tmp.<pid>".
std::vector<fs::path> leftovers(const std::string& run) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (fs::directory_iterator it(run, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const bool next = name.size() > 5 && name.compare(name.size() - 5, 5, kNextSuffix) == 0;
    if (next || name.find(".tmp.") != std::string::npos) out.push_back(it->path());
  }
  return out;
}

Status verify(const std::string& run, const RunState& st) {
  for (const RunStateFile& f : st.files) {
    const std::string path = (fs::path(run) / f.name).string();
    if (!matches(path, f))
      return parse_error(path + " does not match " + run + "/" + kManifestFile + " (iteration " + std::to_string(st.iteration) +
                         "): it was changed, truncated or copied from another run after the run saved it. Restore it, or "
                         "start the run over with --force");
  }
  return Status::Ok();
}

}  // namespace

Expected<platform::FileLock> lock_run_folder(const std::string& run) {
  return platform::FileLock::acquire((fs::path(run) / kRunLockFile).string(), "run folder " + run);
}

Expected<RunState> recover_run_state(const std::string& run) {
  Expected<RunState> read = read_manifest(run);
  if (!read.ok()) return read.status();
  RunState st = std::move(read).value();
  std::error_code ec;
  // Complete an interrupted commit: a ".next" file the manifest lists by checksum is the committed
  // one, so it replaces the old file. Renames are atomic, so each file is old or new, never torn.
  for (const RunStateFile& f : st.files) {
    const fs::path final_path = fs::path(run) / f.name, next = fs::path(run) / (f.name + kNextSuffix);
    if (fs::exists(next, ec) && !matches(final_path.string(), f) && matches(next.string(), f)) {
      fs::rename(next, final_path, ec);
      if (ec) return io_error("cannot complete the interrupted commit of " + run + ": rename " + next.string() + ": " + ec.message());
      st.notes.push_back("completed the interrupted save of iteration " + std::to_string(st.iteration) + " (" + f.name + ")");
    }
  }
  // Anything else left over is an uncommitted attempt: the manifest does not list it.
  for (const fs::path& p : leftovers(run)) {
    fs::remove(p, ec);
    if (ec) return io_error("cannot remove the leftover " + p.string() + ": " + ec.message());
    st.notes.push_back("removed " + p.filename().string() + " left by an interrupted run");
  }
  GS_RETURN_IF_ERROR(verify(run, st));
  return st;
}

Status commit_run_state(const std::string& run, int iteration, const std::string& dataset, const std::string& model_options,
                        const std::vector<std::string>& names) {
  std::error_code ec;
  auto discard = [&] {
    for (const std::string& n : names) fs::remove(fs::path(run) / (n + kNextSuffix), ec);
  };
  nlohmann::json files = nlohmann::json::object();
  for (const std::string& n : names) {
    Expected<RunStateFile> f = describe((fs::path(run) / (n + kNextSuffix)).string(), n);
    if (!f.ok()) {
      discard();
      return f.status();
    }
    files[n] = {{"bytes", f->bytes}, {"fnv1a64", hex64(f->fnv1a64)}};
  }
  nlohmann::json j;
  j["format"] = "hbgs-run-manifest";
  j["version"] = 1;
  j["iteration"] = iteration;
  j["dataset"] = dataset;
  j["model_options"] = nlohmann::json::parse(model_options, nullptr, false);
  j["files"] = std::move(files);
  if (Status st = platform::write_file_atomic((fs::path(run) / kManifestFile).string(), j.dump(2) + "\n"); !st.ok()) {
    discard();  // the old manifest and files still stand
    return st;
  }
  // Committed. A failed rename leaves a ".next" file that recover_run_state moves into place.
  for (const std::string& n : names) {
    fs::rename(fs::path(run) / (n + kNextSuffix), fs::path(run) / n, ec);
    if (ec)
      return io_error("iteration " + std::to_string(iteration) + " is saved, but renaming " + n + kNextSuffix + " into place failed (" +
                      ec.message() + "); the next --resume completes it");
  }
  return Status::Ok();
}

Expected<RunState> check_run_state(const std::string& run) {
  Expected<RunState> st = read_manifest(run);
  if (!st.ok()) return st.status();
  const std::vector<fs::path> left = leftovers(run);
  if (!left.empty()) return io_error(run + ": " + left.front().filename().string() + " is left over from an interrupted write");
  GS_RETURN_IF_ERROR(verify(run, *st));
  return st;
}

}  // namespace gs::jobs
