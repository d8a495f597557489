// SPDX-License-Identifier: MIT
// Fault injection over the jobs' writes (gs::platform::inject_write_fault): for every k, the k-th
// file write of a short training run, a render, an export (every splat format, baked or converted),
// a compact and a report page (an ingest: test_fault_ingest.cpp) fails as a full disk (short write
// or ENOSPC) or a failing disk (EIO). After each failure the output is at a consistent state (a
// training run at its last commit: manifest, model, checkpoint and progress of one iteration, no
// leftovers; a render leaves nothing of itself; a single-file output keeps its previous content or
// stays absent, with no temporary beside it), and resuming or rerunning the command finishes with
// exactly the output of an undisturbed run. Also: kill -9 at random moments, the run
// folder's lock, a checkpoint copied from another run, and --iterations below the checkpoint on resume.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/jobs/compact.h"
#include "gs/jobs/export.h"
#include "gs/jobs/render.h"
#include "gs/jobs/report.h"
#include "gs/jobs/run_folder.h"
#include "gs/jobs/run_state.h"
#include "gs/jobs/train.h"
#include "gs/platform/file.h"
#include "support/run_command.h"

namespace {

namespace fs = std::filesystem;
using gs::platform::WriteFault;

constexpr WriteFault kFaults[] = {WriteFault::kShortWrite, WriteFault::kNoSpace, WriteFault::kIoError};
const char* fault_name(WriteFault f) {
  return f == WriteFault::kShortWrite ? "short write" : f == WriteFault::kNoSpace ? "ENOSPC" : "EIO";
}
// The OS reason each fault must surface as, in the error message.
const char* fault_reason(WriteFault f) { return f == WriteFault::kIoError ? "Input/output error" : "No space left on device"; }

// Calls check(k, fault, context) for every write k of `writes` and every fault: the loop of each case.
void for_each_write_fault(uint64_t writes, const std::string& what,
                          const std::function<void(uint64_t, WriteFault, const std::string&)>& check) {
  for (uint64_t k = 1; k <= writes; ++k)
    for (WriteFault fault : kFaults)
      check(k, fault, what + "write " + std::to_string(k) + " of " + std::to_string(writes) + " fails (" + fault_name(fault) + ")");
}

using gs::test::run;

// One folder per process: ctest runs the cases of this file as separate processes, in parallel.
const fs::path& tmp_root() {
  struct Root {
    fs::path path = fs::path(GS_TEST_TMP) / ("faults_" + std::to_string(long(::getpid())));
    Root() {
      std::error_code ec;
      fs::remove_all(path, ec);
      fs::create_directories(path);
    }
    ~Root() {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  };
  static const Root root;
  return root.path;
}

// A small generated scene (64x48, 8 views of which the synth's test split holds some).
const std::string& scene() {
  static const std::string path = [] {
    const std::string s = (tmp_root() / "scene").string();
    REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + s + " --width 64 --height 48 --views-arc 4 --views-orbit 4 --points 800") == 0);
    return s;
  }();
  return path;
}

std::vector<uint8_t> bytes_of(const fs::path& p) {
  gs::Expected<std::vector<uint8_t>> b = gs::platform::read_file(p.string());
  REQUIRE_MESSAGE(b.ok(), b.status().to_string());
  return *b;
}

gs::jobs::TrainRunOptions short_run(const std::string& out) {
  gs::jobs::TrainRunOptions o;
  o.dataset = scene();
  o.out = out;
  o.iterations = 6;
  o.checkpoint_every = 2;
  o.eval_every = 3;
  o.save_at = "4";
  o.threads = 2;
  o.seed = 3;
  return o;
}

// A short training run, trained once per process: the model that renders, exports and compacts read.
const std::string& trained_run() {
  static const std::string path = [] {
    const std::string r = (tmp_root() / "trained").string();
    const gs::Status st = gs::jobs::train_run(short_run(r), nullptr, nullptr);
    REQUIRE_MESSAGE(st.ok(), st.to_string());
    return r;
  }();
  return path;
}

// Files whose names mark an interrupted write.
std::vector<std::string> leftovers(const fs::path& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string n = it->path().filename().string();
    if (n.find(".tmp.") != std::string::npos || (n.size() > 5 && n.substr(n.size() - 5) == ".next")) out.push_back(it->path().string());
  }
  return out;
}

// A run folder after a failure: either at a commit (manifest, model, checkpoint and progress of one
// iteration) or holding no state file at all.
void check_run_consistent(const fs::path& run, const std::string& context) {
  INFO(context);
  CHECK(leftovers(run).empty());
  if (!fs::exists(run / gs::jobs::kManifestFile)) {
    CHECK_FALSE(fs::exists(run / gs::jobs::kCheckpointFile));
    CHECK_FALSE(fs::exists(run / gs::jobs::kProgressFile));
    CHECK_FALSE(fs::exists(run / gs::jobs::kModelFile));
    return;
  }
  gs::Expected<gs::jobs::RunState> st = gs::jobs::check_run_state(run.string());
  REQUIRE_MESSAGE(st.ok(), st.status().to_string());
  const nlohmann::json progress = nlohmann::json::parse(bytes_of(run / gs::jobs::kProgressFile));
  CHECK(progress.value("iteration", -1) == st->iteration);
  CHECK(progress.value("losses", std::vector<float>()).size() == size_t(st->iteration));
}

}  // namespace

TEST_CASE("fault injection: every write of a short training run fails once, the folder stays committed and --resume finishes it exactly") {
  const fs::path ref = tmp_root() / "train_ref";
  gs::platform::inject_write_fault(0, WriteFault::kNoSpace);
  gs::jobs::TrainRunSummary summary;
  gs::Status st = gs::jobs::train_run(short_run(ref.string()), nullptr, &summary);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  const uint64_t writes = gs::platform::write_file_atomic_calls();
  MESSAGE("an undisturbed run writes " << writes << " files");
  REQUIRE(writes >= 10);
  const std::vector<uint8_t> ref_model = bytes_of(ref / gs::jobs::kModelFile);
  const std::vector<uint8_t> ref_ckpt = bytes_of(ref / gs::jobs::kCheckpointFile);
  const nlohmann::json ref_progress = nlohmann::json::parse(bytes_of(ref / gs::jobs::kProgressFile));
  check_run_consistent(ref, "reference run");

  int resumed = 0, rerun = 0;
  for_each_write_fault(writes, "", [&](uint64_t k, WriteFault fault, const std::string& context) {
    const fs::path out = tmp_root() / "train_fault";
    std::error_code ec;
    fs::remove_all(out, ec);
    gs::platform::inject_write_fault(k, fault);
    st = gs::jobs::train_run(short_run(out.string()), nullptr, nullptr);
    gs::platform::inject_write_fault(0, fault);
    INFO(context);
    REQUIRE_FALSE(st.ok());
    CHECK_MESSAGE(st.message().find(fault_reason(fault)) != std::string::npos, st.to_string());
    check_run_consistent(out, context);
    // The same command again: --resume where the run recorded itself, else a plain rerun.
    gs::jobs::TrainRunOptions again = short_run(out.string());
    again.resume = fs::exists(out / gs::jobs::kRunJson);
    (again.resume ? resumed : rerun) += 1;
    st = gs::jobs::train_run(again, nullptr, nullptr);
    REQUIRE_MESSAGE(st.ok(), st.to_string());
    check_run_consistent(out, context + ", then finished");
    CHECK(bytes_of(out / gs::jobs::kModelFile) == ref_model);
    CHECK(bytes_of(out / gs::jobs::kCheckpointFile) == ref_ckpt);
    const nlohmann::json progress = nlohmann::json::parse(bytes_of(out / gs::jobs::kProgressFile));
    CHECK(progress["losses"] == ref_progress["losses"]);
    CHECK(progress["psnr_rows"].size() == ref_progress["psnr_rows"].size());
    CHECK(fs::exists(out / "model_4.hbgs"));
  });
  MESSAGE((3 * writes) << " failures: " << resumed << " finished by --resume, " << rerun << " by rerunning");
  CHECK(resumed > 0);
}

TEST_CASE("fault injection: every write of a render fails once, nothing of it is left and a rerun gives the same images") {
  gs::Status st;
  // A trained model, and a dataset rendered from its SfM points: the two render paths.
  for (const std::string& input : {trained_run(), scene()}) {
    gs::jobs::RenderRunOptions ro;
    ro.input = input;
    ro.threads = 2;
    ro.out = (tmp_root() / "render_ref").string();
    std::error_code ec;
    fs::remove_all(ro.out, ec);
    gs::platform::inject_write_fault(0, WriteFault::kNoSpace);
    gs::jobs::RenderRunSummary ref;
    st = gs::jobs::render_run(ro, nullptr, &ref);
    REQUIRE_MESSAGE(st.ok(), st.to_string());
    const uint64_t writes = gs::platform::write_file_atomic_calls();
    MESSAGE("an undisturbed render of " << input << " writes " << writes << " files");
    REQUIRE(writes == ref.views.size() + 1);  // one PNG per view and render.json
    for_each_write_fault(writes, input + ": ", [&](uint64_t k, WriteFault fault, const std::string& context) {
      INFO(context);
      const fs::path out = tmp_root() / "render_fault";
      fs::remove_all(out, ec);
      gs::jobs::RenderRunOptions o = ro;
      o.out = out.string();
      gs::platform::inject_write_fault(k, fault);
      st = gs::jobs::render_run(o, nullptr, nullptr);
      gs::platform::inject_write_fault(0, fault);
      REQUIRE_FALSE(st.ok());
      CHECK_MESSAGE(st.message().find(fault_reason(fault)) != std::string::npos, st.to_string());
      CHECK_FALSE(fs::exists(out));
      st = gs::jobs::render_run(o, nullptr, nullptr);
      REQUIRE_MESSAGE(st.ok(), st.to_string());
      for (const gs::jobs::RenderedView& v : ref.views) CHECK(bytes_of(out / v.png) == bytes_of(fs::path(ro.out) / v.png));
    });
  }
}

namespace {

// A command writing the files `outputs` (in the order it writes them) through write_file_atomic.
// Undisturbed it gives the reference bytes; then for every write and fault, starting once from no
// outputs and once from older ones: the command fails naming the OS reason, the files written
// before the failing one are complete, the failing one and those after keep their previous state
// (absent, or the older bytes), no temporary is left beside them, and the same command again
// writes exactly the reference bytes.
void check_single_writes(const std::string& what, const std::vector<fs::path>& outputs, const std::function<gs::Status()>& command) {
  auto set_previous = [&](bool older) {
    for (const fs::path& p : outputs) {
      std::error_code ec;
      fs::remove(p, ec);
      if (older) REQUIRE(gs::platform::write_file_atomic(p.string(), "an older " + p.filename().string()).ok());
    }
  };
  set_previous(false);
  gs::platform::inject_write_fault(0, WriteFault::kNoSpace);
  gs::Status st = command();
  REQUIRE_MESSAGE(st.ok(), (what + ": " + st.to_string()));
  const uint64_t writes = gs::platform::write_file_atomic_calls();
  REQUIRE(writes == outputs.size());
  std::vector<std::vector<uint8_t>> ref;
  for (const fs::path& p : outputs) ref.push_back(bytes_of(p));
  for_each_write_fault(writes, what + ": ", [&](uint64_t k, WriteFault fault, const std::string& context) {
    for (bool older : {false, true}) {
      INFO(context << (older ? ", over older outputs" : ", no outputs before"));
      set_previous(older);
      gs::platform::inject_write_fault(k, fault);
      st = command();
      gs::platform::inject_write_fault(0, fault);
      REQUIRE_FALSE(st.ok());
      CHECK_MESSAGE(st.message().find(fault_reason(fault)) != std::string::npos, st.to_string());
      for (size_t i = 0; i < outputs.size(); ++i) {
        CHECK(leftovers(outputs[i].parent_path()).empty());
        if (i + 1 < k) CHECK(bytes_of(outputs[i]) == ref[i]);
        else if (older) CHECK(gs::platform::read_text_file(outputs[i].string()).value() == "an older " + outputs[i].filename().string());
        else CHECK_FALSE(fs::exists(outputs[i]));
      }
      st = command();
      REQUIRE_MESSAGE(st.ok(), st.to_string());
      for (size_t i = 0; i < outputs.size(); ++i) CHECK(bytes_of(outputs[i]) == ref[i]);
    }
  });
}

}  // namespace

TEST_CASE("fault injection: every write of an export (each format, baked and converted), a compact and a report page fails once, the destination keeps its previous state and a rerun gives the same bytes") {
  const fs::path dir = tmp_root() / "single_writes";
  fs::create_directories(dir);
  for (const char* name : {"model.ply", "model.compressed.ply", "model.splat", "model.spz"}) {
    gs::jobs::ExportRunOptions o;
    o.input = trained_run();
    o.out = (dir / name).string();
    o.distill_iterations = 5;  // the bake's both stages, briefly
    o.evaluate = false;        // reads only
    o.threads = 2;
    check_single_writes(std::string("export to ") + name, {o.out}, [&] { return gs::jobs::export_run(o, nullptr); });
  }
  {  // A splat file converted to another format (here .spz version 3, the gzip one).
    gs::jobs::ExportRunOptions o;
    o.input = (dir / "model.ply").string();
    o.out = (dir / "converted.spz").string();
    o.write.spz.version = 3;
    o.evaluate = false;
    REQUIRE(fs::exists(o.input));
    check_single_writes("conversion of model.ply to .spz", {o.out}, [&] { return gs::jobs::export_run(o, nullptr); });
  }
  {
    gs::jobs::CompactRunOptions o;
    o.input = trained_run();
    o.out = (dir / "model.hbgc").string();
    o.evaluate = false;
    o.threads = 2;
    check_single_writes("compact", {o.out}, [&] { return gs::jobs::compact_run(o, nullptr); });
  }
  {
    gs::jobs::ReportRunOptions o;
    o.run = trained_run();
    o.out = (dir / "report.html").string();
    o.distill_iterations = 5;
    o.views = 1;
    o.threads = 2;
    check_single_writes("report page", {o.out}, [&] { return gs::jobs::report_run(o, nullptr); });
  }
}

TEST_CASE("run folder: a second writer is refused while the first holds the lock") {
  const fs::path out = tmp_root() / "locked";
  fs::create_directories(out);
  gs::Expected<gs::platform::FileLock> held = gs::jobs::lock_run_folder(out.string());
  REQUIRE(held.ok());
  const gs::Status st = gs::jobs::train_run(short_run(out.string()), nullptr, nullptr);
  REQUIRE_FALSE(st.ok());
  CHECK_MESSAGE(st.message().find("in use by another hbgs process") != std::string::npos, st.to_string());
  CHECK_FALSE(fs::exists(out / gs::jobs::kRunJson));
  *held = gs::platform::FileLock();  // released: now it trains
  const gs::Status again = gs::jobs::train_run(short_run(out.string()), nullptr, nullptr);
  CHECK_MESSAGE(again.ok(), again.to_string());
}

TEST_CASE("run folder: --resume refuses a checkpoint copied from another run and --iterations below the checkpoint") {
  const fs::path a = tmp_root() / "run_a", b = tmp_root() / "run_b";
  gs::jobs::TrainRunOptions oa = short_run(a.string()), ob = short_run(b.string());
  ob.seed = 4;
  ob.iterations = 4;
  REQUIRE(gs::jobs::train_run(oa, nullptr, nullptr).ok());
  REQUIRE(gs::jobs::train_run(ob, nullptr, nullptr).ok());

  // --iterations below the checkpoint: refused, and run.json still records the run's own count.
  gs::jobs::TrainRunOptions fewer = oa;
  fewer.resume = true;
  fewer.iterations = 3;
  fewer.given = {"iterations"};
  gs::Status st = gs::jobs::train_run(fewer, nullptr, nullptr);
  REQUIRE_FALSE(st.ok());
  CHECK_MESSAGE(st.message().find("below the checkpoint's iteration 6") != std::string::npos, st.to_string());
  CHECK(nlohmann::json::parse(bytes_of(a / gs::jobs::kRunJson))["options"]["iterations"] == 6);

  // B's checkpoint (seed 4) copied into A (seed 3): the manifest's checksum no longer matches.
  fs::copy_file(b / gs::jobs::kCheckpointFile, a / gs::jobs::kCheckpointFile, fs::copy_options::overwrite_existing);
  gs::jobs::TrainRunOptions more = oa;
  more.resume = true;
  more.iterations = 8;
  more.given = {"iterations"};
  st = gs::jobs::train_run(more, nullptr, nullptr);
  REQUIRE_FALSE(st.ok());
  CHECK_MESSAGE(st.message().find("does not match") != std::string::npos, st.to_string());
  // ... and with B's manifest copied too, the model options recorded beside it differ from A's run.json.
  fs::copy_file(b / gs::jobs::kManifestFile, a / gs::jobs::kManifestFile, fs::copy_options::overwrite_existing);
  for (const char* f : {gs::jobs::kModelFile, gs::jobs::kProgressFile})
    fs::copy_file(b / f, a / f, fs::copy_options::overwrite_existing);
  st = gs::jobs::train_run(more, nullptr, nullptr);
  REQUIRE_FALSE(st.ok());
  CHECK_MESSAGE(st.message().find("other model options") != std::string::npos, st.to_string());
}

TEST_CASE("run state: recovery completes a commit interrupted among its renames and discards an uncommitted one") {
  const fs::path run = tmp_root() / "recover";
  std::error_code ec;
  fs::remove_all(run, ec);
  REQUIRE(gs::jobs::train_run(short_run(run.string()), nullptr, nullptr).ok());
  const gs::Expected<gs::jobs::RunState> committed = gs::jobs::check_run_state(run.string());
  REQUIRE(committed.ok());
  CHECK(committed->iteration == 6);
  auto write = [](const fs::path& p, const std::string& text) { REQUIRE(gs::platform::write_file_atomic(p.string(), text).ok()); };

  // A commit killed after its manifest: two of the three files still wait under ".next".
  const std::vector<uint8_t> model = bytes_of(run / "model.hbgs"), progress = bytes_of(run / "progress.json");
  fs::rename(run / "model.hbgs", run / "model.hbgs.next");
  fs::rename(run / "progress.json", run / "progress.json.next");
  write(run / "model.hbgs", "an older model");
  write(run / "progress.json", "{}");
  CHECK_FALSE(gs::jobs::check_run_state(run.string()).ok());
  gs::Expected<gs::jobs::RunState> rec = gs::jobs::recover_run_state(run.string());
  REQUIRE_MESSAGE(rec.ok(), rec.status().to_string());
  CHECK(rec->notes.size() == 2);
  CHECK(bytes_of(run / "model.hbgs") == model);
  CHECK(bytes_of(run / "progress.json") == progress);
  CHECK(gs::jobs::check_run_state(run.string()).ok());

  // A commit killed before its manifest, and a temporary of a killed write: both discarded.
  write(run / "checkpoint.bin.next", "half a checkpoint");
  write(run / "progress.json.tmp.4242", "partial");
  rec = gs::jobs::recover_run_state(run.string());
  REQUIRE(rec.ok());
  CHECK(rec->notes.size() == 2);
  CHECK(rec->iteration == 6);
  CHECK(leftovers(run).empty());

  // A state file changed behind the run's back: refused, naming it.
  write(run / "progress.json", "{\"iteration\": 6}");
  rec = gs::jobs::recover_run_state(run.string());
  REQUIRE_FALSE(rec.ok());
  CHECK_MESSAGE(rec.status().message().find("progress.json does not match") != std::string::npos, rec.status().to_string());
  // A manifest that is not one: refused too, never trusted.
  write(run / "manifest.json", "{\"format\": \"hbgs-run-manifest\", \"version\": 1, \"iteration\": 6, \"files\": {\"../x\": {}}}");
  rec = gs::jobs::recover_run_state(run.string());
  REQUIRE_FALSE(rec.ok());
  CHECK_MESSAGE(rec.status().message().find("not a plain name") != std::string::npos, rec.status().to_string());
}

TEST_CASE("run folder: a run that failed before its first checkpoint restarts with --resume, a plain train says so") {
  const fs::path run = tmp_root() / "no_checkpoint";
  std::error_code ec;
  fs::remove_all(run, ec);
  gs::jobs::TrainRunOptions o = short_run(run.string());
  o.seed = 11;  // recorded in run.json; the restart must use it
  gs::platform::inject_write_fault(3, WriteFault::kNoSpace);  // after run.json, before the first commit
  gs::Status st = gs::jobs::train_run(o, nullptr, nullptr);
  gs::platform::inject_write_fault(0, WriteFault::kNoSpace);
  REQUIRE_FALSE(st.ok());
  REQUIRE(fs::exists(run / gs::jobs::kRunJson));
  REQUIRE_FALSE(fs::exists(run / gs::jobs::kManifestFile));

  st = gs::jobs::train_run(short_run(run.string()), nullptr, nullptr);
  REQUIRE_FALSE(st.ok());
  CHECK_MESSAGE(st.message().find("stopped before its first checkpoint; pass --resume") != std::string::npos, st.to_string());

  gs::jobs::TrainRunOptions resume = short_run(run.string());
  resume.resume = true;  // seed not given: it comes from run.json
  std::vector<std::string> notes;
  st = gs::jobs::train_run(resume, [&](const gs::jobs::TrainEvent& e) {
    if (e.kind == gs::jobs::TrainEvent::kNote) notes.push_back(e.message);
  }, nullptr);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  bool said = false;
  for (const std::string& n : notes) said = said || n.find("restarting it from iteration 0") != std::string::npos;
  CHECK(said);
  CHECK(nlohmann::json::parse(bytes_of(run / gs::jobs::kRunJson))["options"]["seed"] == 11);
  CHECK(gs::jobs::check_run_state(run.string()).ok());
}

TEST_CASE("run folder: kill -9 at random moments leaves a committed state that --resume finishes exactly") {
  gs::jobs::TrainRunOptions o = short_run((tmp_root() / "kill_ref").string());
  o.iterations = 30;
  o.checkpoint_every = 1;  // a commit every iteration: kills land inside commits too
  o.eval_every = 5;
  o.save_at = "20";
  REQUIRE(gs::jobs::train_run(o, nullptr, nullptr).ok());
  const std::vector<uint8_t> ref_model = bytes_of(fs::path(o.out) / gs::jobs::kModelFile);
  std::mt19937 rng(12345);
  int interrupted = 0;
  for (int trial = 0; trial < 6; ++trial) {
    gs::jobs::TrainRunOptions k = o;
    k.out = (tmp_root() / "kill").string();
    std::error_code ec;
    fs::remove_all(k.out, ec);
    // The kill lands a random 0-30 ms after the run committed a random iteration of 2-20: inside
    // later steps, evaluations and commits (a commit takes milliseconds: three fsynced files).
    const int target = std::uniform_int_distribution<int>(2, 20)(rng);
    const int delay_ms = std::uniform_int_distribution<int>(0, 30)(rng);
    const pid_t child = ::fork();
    REQUIRE(child >= 0);
    if (child == 0) _exit(gs::jobs::train_run(k, nullptr, nullptr).ok() ? 0 : 1);
    const fs::path manifest = fs::path(k.out) / gs::jobs::kManifestFile;
    for (int waited = 0; waited < 60000; ++waited) {
      gs::Expected<std::string> text = gs::platform::read_text_file(manifest.string());
      const nlohmann::json j = text.ok() ? nlohmann::json::parse(*text, nullptr, false) : nlohmann::json();
      if (j.is_object() && j.value("iteration", 0) >= target) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    const bool killed = WIFSIGNALED(status);
    interrupted += killed;
    INFO("trial " << trial << ": killed " << delay_ms << " ms after iteration " << target << (killed ? "" : " (it had finished)"));
    if (fs::exists(fs::path(k.out) / gs::jobs::kManifestFile)) {
      gs::Expected<gs::jobs::RunState> st = gs::jobs::recover_run_state(k.out);
      REQUIRE_MESSAGE(st.ok(), st.status().to_string());
      CHECK(gs::jobs::check_run_state(k.out).ok());
    }
    k.resume = fs::exists(fs::path(k.out) / gs::jobs::kRunJson);
    const gs::Status st = gs::jobs::train_run(k, nullptr, nullptr);
    REQUIRE_MESSAGE(st.ok(), st.to_string());
    CHECK(bytes_of(fs::path(k.out) / gs::jobs::kModelFile) == ref_model);
  }
  CHECK(interrupted == 6);
}

TEST_CASE("run folder: --force replaces a run whose state is damaged, without it the damage is reported") {
  const fs::path run = tmp_root() / "damaged";
  std::error_code ec;
  fs::remove_all(run, ec);
  REQUIRE(gs::jobs::train_run(short_run(run.string()), nullptr, nullptr).ok());
  REQUIRE(gs::platform::write_file_atomic((run / gs::jobs::kCheckpointFile).string(), std::string("garbage")).ok());
  gs::jobs::TrainRunOptions o = short_run(run.string());
  o.resume = true;
  gs::Status st = gs::jobs::train_run(o, nullptr, nullptr);
  REQUIRE_FALSE(st.ok());
  CHECK_MESSAGE(st.message().find("checkpoint.bin does not match") != std::string::npos, st.to_string());
  o.resume = false;
  o.force = true;
  st = gs::jobs::train_run(o, nullptr, nullptr);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  CHECK(gs::jobs::check_run_state(run.string()).ok());
}
