// SPDX-License-Identifier: MIT
// Fault injection over an ingest (gs::platform::inject_write_fault; real COLMAP, so labelled e2e):
// replacing an existing dataset with --force, the k-th file write fails as a full or failing disk for
// every k (the fault kinds in turn). Each time the old dataset is left exactly as it was and no
// half-written dataset appears; the same command run again replaces it.
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>

#include <doctest/doctest.h>

#include "gs/capture/ingest.h"
#include "gs/platform/file.h"
#include "support/run_command.h"

namespace {

namespace fs = std::filesystem;
using gs::platform::WriteFault;

using gs::test::run;

// Every file under dir (relative name -> bytes).
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    gs::Expected<std::string> text = gs::platform::read_text_file(e.path().string());
    REQUIRE(text.ok());
    out[fs::relative(e.path(), dir).string()] = *text;
  }
  return out;
}

// The names directly in dir.
std::set<std::string> entries(const fs::path& dir) {
  std::set<std::string> out;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) out.insert(e.path().filename().string());
  return out;
}

}  // namespace

TEST_CASE("fault injection: every write of an ingest fails once, the dataset it replaces survives and a rerun succeeds (e2e, COLMAP)") {
  gs::capture::IngestOptions o;
  o.select.target_count = 10;
  o.colmap.permissive_registration = true;  // few, small frames
  o.colmap.threads = 2;
  o.force = true;
  if (!gs::capture::check_colmap(o.colmap).ok()) {
    MESSAGE("[SKIPPED: COLMAP is not installed (apt install colmap)]");
    return;
  }
  const fs::path tmp = fs::path(GS_TEST_TMP) / "fault_ingest";
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp);
  // A handheld-like path of 16 frames; the ingest keeps 10 of them.
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --path-frames 16 --path-sweep 40 --out " + (tmp / "path").string() +
              " --width 320 --height 240") == 0);
  const std::string frames = (tmp / "path" / "frames").string();
  const gs::capture::SourceFactory source = [&] { return gs::capture::open_input(frames); };
  const fs::path ds = tmp / "ds";

  gs::platform::inject_write_fault(0, WriteFault::kNoSpace);
  gs::capture::IngestReport rep;
  gs::Status st = gs::capture::ingest(source, ds.string(), o, nullptr, &rep);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  const uint64_t writes = gs::platform::write_file_atomic_calls();
  MESSAGE("an undisturbed ingest writes " << writes << " files; COLMAP registered " << rep.colmap.registered << " of "
                                          << rep.colmap.images);
  REQUIRE(writes == rep.kept_frames.size() + 1);  // the kept frames and ingest.json
  std::map<std::string, std::string> before = snapshot(ds);

  // Write k fails as the (k mod 3)-th kind: every write fails once and every kind fails several
  // writes (the kinds differ only in the errno they report). After each failure the old dataset is
  // as it was and only the failed run's work folder is beside it, which a run clears before it
  // starts: whichever write failed, a rerun starts from the same state, and one rerun at the end
  // shows that the command run again replaces it. (A rerun after every failure, and every kind at
  // every write, ran COLMAP 45 times: 133 s in CI's release tests.)
  const WriteFault faults[] = {WriteFault::kShortWrite, WriteFault::kNoSpace, WriteFault::kIoError};
  REQUIRE(writes >= 3);
  // A failed ingest leaves its work in ds.partial (the next run clears it before it starts, so no
  // run resumes from it) and nothing else.
  std::set<std::string> after_failure = entries(tmp);
  after_failure.insert(ds.filename().string() + ".partial");
  for (uint64_t k = 1; k <= writes; ++k) {
    const WriteFault fault = faults[k % 3];
    INFO("write " << k << " of " << writes << " fails (kind " << int(fault) << ")");
    gs::platform::inject_write_fault(k, fault);
    st = gs::capture::ingest(source, ds.string(), o, nullptr, nullptr);
    gs::platform::inject_write_fault(0, fault);
    REQUIRE_FALSE(st.ok());
    CHECK_MESSAGE(st.message().find(fault == WriteFault::kIoError ? "Input/output error" : "No space left on device") != std::string::npos,
                  st.to_string());
    CHECK(snapshot(ds) == before);  // the old dataset is untouched
    CHECK(entries(tmp) == after_failure);  // and beside it only the failed run's work folder
  }
  // The same command again replaces it: the same frames, so the same image files.
  st = gs::capture::ingest(source, ds.string(), o, nullptr, nullptr);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  const std::map<std::string, std::string> after = snapshot(ds);
  for (const auto& [name, bytes] : before)
    if (name.rfind("images/", 0) == 0) CHECK(after.count(name) == 1);
  CHECK(after.count("ingest.json") == 1);
  CHECK(after.size() == before.size());
  fs::remove_all(tmp, ec);
}
