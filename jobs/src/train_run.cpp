// SPDX-License-Identifier: MIT
// The training job's run folder (gs/jobs/train.h train_run): the arguments checked before anything
// is written, the folder created, locked and recovered, a prepared session (train_session.cpp)
// trained with evaluations and atomic commits of the state (run.json, checkpoint.bin +
// progress.json, psnr_vs_time.csv/.svg, models, results.json / per_view.json, refined poses).
#include <algorithm>
#include <filesystem>
#include <functional>
#include <system_error>

#include <nlohmann/json.hpp>

#include "gs/jobs/run_folder.h"
#include "gs/jobs/run_state.h"
#include "gs/metrics/lpips.h"
#include "gs/platform/clock.h"
#include "gs/platform/file.h"
#include "gs/stats.h"
#include "json_util.h"
#include "text_util.h"
#include "time_budget.h"
#include "train_options.h"
#include "train_progress.h"
#include "train_session_state.h"

namespace gs::jobs {

namespace {

namespace fs = std::filesystem;

// Files a previous run left in `run` (removed by force; their presence refuses a plain train).
std::vector<fs::path> run_outputs(const std::string& run) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const char* name : {kRunJson, kCheckpointFile, kProgressFile, kPsnrCsv, kPsnrSvg, kResultsJson, kPerViewJson,
                           kModelFile, "test"})
    if (fs::exists(fs::path(run) / name, ec)) out.push_back(fs::path(run) / name);
  for (fs::directory_iterator it(run, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("model_", 0) == 0 && it->path().extension() == ".hbgs") out.push_back(it->path());
  }
  return out;
}

Status at_iteration(int it, const Status& st) { return Status(st.code(), "iteration " + std::to_string(it) + ": " + st.message()); }

}  // namespace

// One train_run: its steps in the order run() takes them. A friend of TrainSession (it reads the
// session's state: test views, pose truth, SfM report).
class TrainRun {
 public:
  TrainRun(const TrainRunOptions& options, const TrainProgressFn& progress)
      : say_(progress ? progress : [](const TrainEvent&) {}), a_(options) {}
  Status run(TrainRunSummary* summary);

 private:
  void note(const std::string& m) const { say_(text_event(TrainEvent::kNote, m)); }
  // 1. Everything that can be wrong with the arguments, checked before the run folder is touched.
  Status check_arguments() const;
  // 2. The run folder: created if new (and removed again when the run fails before training
  // starts), locked against a second writer, and brought to its last committed state.
  Status open_run_folder();
  // With --resume: the recorded options, and what there is to continue (checkpoint, legacy
  // checkpoint, or nothing: a restart with the recorded options).
  Status resolve_resume();
  // What the folder holds refuses a plain train; --save-at and --pose-init sfm are checked.
  Status check_before_session();
  // The session (dataset, pose stages, model, trainer), the checkpoint on --resume, LPIPS weights.
  Status prepare_session();
  // 3. Start: clear a replaced run, record the options, announce the run.
  Status start();
  // 4. Train. Order per iteration: step, evaluations (renders and results), the commit, then the
  // PSNR files derived from the committed progress.
  Status train();
  // With a time budget: the pace of a step, and when due the run's new predicted length given to
  // the trainer (set_run_length, Trainer::retarget).
  Status steer_by_budget(int it, double seconds);
  // Training seconds left of the budget (0 without one).
  double remaining_seconds() const { return budget_ ? std::max(0.0, budget_->budget() - prog_.train_seconds) : 0.0; }
  nlohmann::json budget_json(int it) const;
  Status after_step(int it);
  // The test PSNR alone (PSNR-vs-time rows).
  Status quick_psnr(int it);
  // Evaluates every test view fully (PNGs, SSIM, LPIPS) and merges the figures as "ours_<it>" into
  // results.json / per_view.json.
  Status full_eval(int it);
  // The last step is done: its gradient and growth buffers and the training photos go before the
  // final evaluation renders and measures (the memory peak would otherwise be the sum of both).
  void release_for_final_eval() {
    trainer_->release_step_memory();
    d_->release_training_pixels();
  }
  // Optimised poses: the test views in the model's frame, registered (TrainSession::Impl::
  // test_views_in_model_frame, register_test_views), with the PSNR at the dataset poses and at the
  // mapped ones beside in *report.
  Status registered_test_views(const model::EvalOptions& eo, std::vector<io::DatasetView>* registered, nlohmann::json* report);
  nlohmann::json eval_extra(int it, const model::EvalResult& r) const;
  void add_psnr_row(int it, double psnr);
  // Saves the training state at the current iteration as one commit (gs/jobs/run_state.h): the
  // model, checkpoint and progress under ".next" names, then the manifest, then the renames. The
  // save_at snapshots model_<it>.hbgs are separate files outside the state.
  Status commit();
  bool listed(int it) const { return std::binary_search(save_at_.begin(), save_at_.end(), it); }
  // 5. Resuming a finished run evaluates its final model again (the summary needs it); refined
  // poses are written.
  Status finish();
  void summarise(TrainRunSummary* summary) const;
  // Views held back since SfM could not register them: which are still held (never trained on).
  nlohmann::json held_back_json() const;
  nlohmann::json pose_json() const;

  // Removes a run folder this run created when it fails before training starts (declared after
  // the lock, so it runs while the lock is still held, and before the session, which goes first).
  struct RemoveIfUnstarted {
    const TrainRun& run;
    ~RemoveIfUnstarted() {
      std::error_code ignored;
      if (run.created_ && !run.training_started_) fs::remove_all(run.a_.out, ignored);
    }
  };

  const TrainProgressFn say_;
  TrainRunOptions a_;
  bool created_ = false, training_started_ = false;
  platform::FileLock lock_;
  RemoveIfUnstarted cleanup_{*this};
  RunState state_;
  std::string ckpt_;
  bool have_run_json_ = false, legacy_checkpoint_ = false;
  std::vector<fs::path> previous_;
  std::vector<int> save_at_;
  std::unique_ptr<TrainSession> session_;
  TrainSession::Impl* d_ = nullptr;       // session_'s state
  model::Trainer* trainer_ = nullptr;     // session_'s trainer
  // The LPIPS network (about 9.5 MB of weights) is loaded at set-up to check it, then held only
  // while an evaluation runs: kept through training it was resident for the whole run.
  bool have_lpips_ = false;
  std::string title_, dataset_abs_, model_options_, model_path_;
  Progress prog_;
  StageTimes stage_times_;  // the current step's stages (reset after each step, summed into prog_)
  int resumed_from_ = -1, last_full_ = -1;
  bool have_test_ = false;
  model::EvalResult final_eval_;
  std::unique_ptr<TimeBudget> budget_;
  int planned_iterations_ = 0;  // the run's length: a_.iterations, or the time budget's prediction
  bool final_ = false;          // the iteration being finished is the run's last
};

Status TrainRun::check_arguments() const {
  std::error_code ec;
  if (a_.out.empty()) return invalid_argument("no run folder given (--out)");
  GS_RETURN_IF_ERROR(check_dataset_path(a_.dataset));
  if (a_.resume && a_.force) return invalid_argument("--resume and --force contradict each other; choose one");
  if (fs::exists(a_.out, ec) && !fs::is_directory(a_.out, ec)) return invalid_argument("output " + a_.out + " is not a directory");
  return check_output_outside_dataset(a_.out, a_.dataset);
}

Status TrainRun::open_run_folder() {
  std::error_code ec;
  created_ = !fs::exists(a_.out, ec);
  GS_RETURN_IF_ERROR(platform::make_dirs(a_.out));
  Expected<platform::FileLock> lock = lock_run_folder(a_.out);
  if (!lock.ok()) {
    if (created_) fs::remove_all(a_.out, ec);
    created_ = false;  // removed here already
    return lock.status();
  }
  lock_ = std::move(lock).value();
  Expected<RunState> state = recover_run_state(a_.out);
  // --force replaces whatever is there, a damaged state included (run_outputs lists the manifest).
  if (!state.ok() && a_.force) state = RunState{};
  if (!state.ok()) return Status(state.status().code(), (a_.resume ? "--resume: " : "") + state.status().message());
  state_ = std::move(state).value();
  for (const std::string& n : state_.notes) note(n);
  ckpt_ = (fs::path(a_.out) / kCheckpointFile).string();
  have_run_json_ = platform::file_exists((fs::path(a_.out) / kRunJson).string());
  legacy_checkpoint_ = !state_.committed && platform::file_exists(ckpt_);  // a run from before manifests
  return Status::Ok();
}

Status TrainRun::resolve_resume() {
  if (!a_.resume) return Status::Ok();
  if (!have_run_json_) return invalid_argument("nothing to resume: " + a_.out + " holds no run (" + kRunJson + " not found)");
  if (Status st = apply_recorded_options(a_.out, &a_); !st.ok()) return Status(st.code(), "--resume: " + st.message());
  bool from_checkpoint = false;
  if (state_.committed) {
    if (state_.dataset != absolute_path(a_.dataset))
      return invalid_argument("--resume: " + a_.out + "/" + kManifestFile + " says the checkpoint was trained on " + state_.dataset +
                              ", not " + absolute_path(a_.dataset));
    if (state_.model_options != model_options_json(a_))
      return invalid_argument("--resume: the checkpoint in " + a_.out + " was made with other model options than " + kRunJson +
                              " records (checkpoint: " + state_.model_options + "; run.json: " + model_options_json(a_) +
                              "); was it copied from another run? Start over with --force");
    from_checkpoint = true;
  } else if (legacy_checkpoint_) {
    note(ckpt_ + " has no " + kManifestFile + " beside it (a run from an older hbgs): resuming it as it is");
    from_checkpoint = true;
  } else {
    // Failed or killed before its first checkpoint: nothing to continue, so it restarts with the
    // options it recorded.
    note(a_.out + " has no checkpoint yet (the run stopped before its first one): restarting it from iteration 0 with the options in " +
         kRunJson);
    a_.force = true;
  }
  a_.resume = from_checkpoint;
  return Status::Ok();
}

Status TrainRun::check_before_session() {
  // The automatic offsets per anchor are decided once and recorded as a number (run.json, the
  // checkpoint's model options): a resumed run keeps them whatever budget it is given.
  a_.offsets = effective_offsets(a_);
  previous_ = run_outputs(a_.out);
  if (!a_.resume && !previous_.empty() && !a_.force) {
    if (have_run_json_ && !state_.committed && !legacy_checkpoint_)
      return invalid_argument(a_.out + " holds a run that stopped before its first checkpoint; pass --resume to restart it with its "
                              "recorded options or --force to replace it");
    return invalid_argument(a_.out + " already holds a run (" + previous_.front().string() +
                            " exists); pass --force to overwrite it or --resume to continue it");
  }
  if (!(a_.time_budget >= 0 && a_.time_budget <= 1e7))
    return invalid_argument("the time budget must be between 0 (none) and 10000000 seconds, not " + std::to_string(a_.time_budget));
  Expected<std::vector<int>> save_at = parse_save_at(a_.save_at);
  if (!save_at.ok()) return save_at.status();
  save_at_ = std::move(save_at).value();
  if (a_.pose_init == "sfm") {
    if (!a_.optimize_poses) return invalid_argument("--pose-init sfm needs --optimize-poses");
    if (a_.sfm_pose_init) GS_RETURN_IF_ERROR(a_.sfm_pose_init->check(dataset_folder(a_.dataset), a_.sfm_images, a_.colmap));
    else if (!a_.resume) return no_sfm_pose_initializer();
  }
  return Status::Ok();
}

Status TrainRun::prepare_session() {
  Expected<std::unique_ptr<TrainSession>> session = TrainSession::create(a_, say_, a_.out);
  if (!session.ok()) return session.status();
  session_ = std::move(session).value();
  d_ = session_->impl_.get();
  trainer_ = d_->trainer.get();
  if (a_.resume) {
    if (Status st = trainer_->load_checkpoint(ckpt_); !st.ok()) return Status(st.code(), "cannot resume from " + ckpt_ + ": " + st.message());
    if (state_.committed && trainer_->iteration() != state_.iteration)
      return parse_error(ckpt_ + " is at iteration " + std::to_string(trainer_->iteration()) + " but " + kManifestFile + " says " +
                         std::to_string(state_.iteration));
    if (a_.iterations < trainer_->iteration())
      return invalid_argument("--iterations " + std::to_string(a_.iterations) + " is below the checkpoint's iteration " +
                              std::to_string(trainer_->iteration()) + ": a resumed run can only continue (the models it saved on "
                              "the way are model_<iteration>.hbgs)");
  }
  std::string lpips_note;
  Expected<std::unique_ptr<metrics::LpipsAlex>> lpips = load_lpips(a_.lpips_weights, a_.threads, &lpips_note);
  if (!lpips.ok()) return lpips.status();
  if (!lpips_note.empty()) note(lpips_note);
  have_lpips_ = *lpips != nullptr;
  return Status::Ok();
}

Status TrainRun::start() {
  std::error_code ec;
  if (a_.force)
    for (const fs::path& p : previous_)
      if (fs::remove_all(p, ec), ec) return io_error("cannot remove " + p.string() + ": " + ec.message());
  GS_RETURN_IF_ERROR(platform::write_file_atomic((fs::path(a_.out) / kRunJson).string(), run_json(a_, trainer_->model().frame)));
  training_started_ = true;

  title_ = "Test PSNR vs training time: " + fs::path(absolute_path(a_.dataset)).filename().string();
  if (a_.resume) prog_ = load_progress(a_.out, trainer_->iteration(), [this](const std::string& m) { note(m); });
  resumed_from_ = a_.resume ? trainer_->iteration() : -1;
  have_test_ = !d_->test_views.empty();
  if (!have_test_) note("the dataset has no test views; nothing is evaluated");
  dataset_abs_ = absolute_path(a_.dataset);
  model_options_ = model_options_json(a_);
  model_path_ = (fs::path(a_.out) / kModelFile).string();
  say_(text_event(TrainEvent::kStage, a_.dataset + ", " + std::to_string(d_->train_views.size()) + " train + " +
                                          std::to_string(d_->test_views.size()) + " test views, " +
                                          std::to_string(d_->dataset.points_xyz.size() / 3) + " points, " +
                                          std::to_string(trainer_->model().anchor_count) + " anchors, image features " +
                                          a_.image_features + ", ISA " + d_->kernels->isa + ", " +
                                          std::to_string(d_->pool->num_threads()) + " threads" +
                                          (a_.resume ? ", resuming at iteration " + std::to_string(trainer_->iteration()) : "")));
  // The PSNR files are derived from progress; after a resume they show the committed rows only.
  if (a_.resume) GS_RETURN_IF_ERROR(write_psnr_files(a_.out, prog_.rows, title_));
  return Status::Ok();
}

nlohmann::json TrainRun::held_back_json() const {
  // Why each view was held back at the start (a resumed run's session did not check again: its
  // lists are empty; still_held and repaired come from the checkpoint), and where those views are now.
  nlohmann::json unregistered = nlohmann::json::array(), suspect = nlohmann::json::array(), sfm_doubted = nlohmann::json::array();
  nlohmann::json moved_far = nlohmann::json::array();
  nlohmann::json still = nlohmann::json::array(), repaired = nlohmann::json::array(), confirmed = nlohmann::json::array();
  const std::vector<uint8_t>& held = trainer_->held_back();
  const std::vector<uint8_t>& moved = trainer_->repaired();
  size_t at_start = 0;
  for (size_t i = 0; i < held.size(); ++i) {
    const bool unreg = i < d_->sfm_registered.size() && !d_->sfm_registered[i];
    const bool doubted = i < d_->sfm_suspect.size() && d_->sfm_suspect[i];
    const bool susp = i < d_->suspect.size() && d_->suspect[i];
    const bool far = i < d_->alignment_doubted.size() && d_->alignment_doubted[i];
    if (unreg) unregistered.push_back(d_->train_names[i]);
    if (doubted) sfm_doubted.push_back(d_->train_names[i]);
    if (susp) suspect.push_back(d_->train_names[i]);
    if (far) moved_far.push_back(d_->train_names[i]);
    const bool held_at_start = unreg || doubted || susp || far;
    if (held_at_start) ++at_start;
    if (held[i]) still.push_back(d_->train_names[i]);
    else if (moved[i]) repaired.push_back(d_->train_names[i]);
    else if (held_at_start) confirmed.push_back(d_->train_names[i]);
  }
  return nlohmann::json{{"at_start", at_start},
                        {"not_registered_by_sfm", unregistered},
                        {"doubted_by_sfm_check", sfm_doubted},
                        {"contradicted_by_points", suspect},
                        {"moved_far_by_point_alignment", moved_far},
                        {"repaired", repaired},
                        {"confirmed_at_given_pose", confirmed},
                        {"still_held", still}};
}

nlohmann::json TrainRun::pose_json() const {
  const std::vector<Pose> now = poses_of(trainer_->cameras());
  return nlohmann::json{{"noise", a_.pose_noise},
                        {"noise_on", a_.pose_noise_on},
                        {"optimized", a_.optimize_poses},
                        {"scene_radius", d_->truth.radius * d_->truth.unit},
                        {"train_input", pose_errors_json(d_->input_errors, true, d_->train_names)},
                        {"sfm_init", d_->sfm_init},
                        {"point_alignment", d_->point_alignment},
                        {"view_check", d_->view_check},
                        {"train_final", pose_errors_json(d_->errors(now, true), true, d_->train_names)},
                        {"train_final_unaligned", pose_errors_json(d_->errors(now, false), false)},
                        {"held_back", held_back_json()}};
}

void TrainRun::add_psnr_row(int it, double psnr) {
  prog_.rows.erase(std::remove_if(prog_.rows.begin(), prog_.rows.end(), [it](const PsnrRow& r) { return r.iteration >= it; }),
                   prog_.rows.end());
  prog_.rows.push_back({it, prog_.train_seconds, psnr});
}

Status TrainRun::quick_psnr(int it) {
  model::EvalOptions quick;
  quick.psnr_only = true;
  std::copy(trainer_->options().background.rgb, trainer_->options().background.rgb + 3, quick.render.background);
  nlohmann::json frame;
  const std::vector<io::DatasetView> mapped = a_.optimize_poses ? d_->test_views_in_model_frame(&frame) : std::vector<io::DatasetView>{};
  Expected<model::EvalResult> r =
      model::evaluate_views(*trainer_, a_.optimize_poses ? pointers_to(mapped) : d_->test_views, quick, d_->pool.get());
  if (!r.ok()) return r.status();
  add_psnr_row(it, r->psnr);
  return Status::Ok();
}

Status TrainRun::registered_test_views(const model::EvalOptions& eo, std::vector<io::DatasetView>* registered,
                                       nlohmann::json* report) {
  say_(text_event(TrainEvent::kStage, "registering " + std::to_string(d_->test_views.size()) + " test views against the model..."));
  model::EvalOptions quick;
  quick.psnr_only = true;
  quick.render = eo.render;
  Expected<model::EvalResult> at_dataset = model::evaluate_views(*trainer_, d_->test_views, quick, d_->pool.get());
  if (!at_dataset.ok()) return at_dataset.status();
  *registered = d_->test_views_in_model_frame(report);
  Expected<model::EvalResult> at_mapped = model::evaluate_views(*trainer_, pointers_to(*registered), quick, d_->pool.get());
  if (!at_mapped.ok()) return at_mapped.status();
  GS_RETURN_IF_ERROR(d_->register_test_views(registered, report));
  (*report)["PSNR_at_dataset_poses"] = at_dataset->psnr;
  (*report)["PSNR_at_mapped_poses"] = at_mapped->psnr;
  return Status::Ok();
}

nlohmann::json TrainRun::eval_extra(int it, const model::EvalResult& r) const {
  const model::HybridModel& m = trainer_->model();
  double gaussians = 0;
  for (const model::ViewMetrics& v : r.views) gaussians += double(v.gaussians);
  return {{"iterations", it},
          {"train_seconds", prog_.train_seconds},
          {"train_cpu_seconds", prog_.train_cpu_seconds},
          {"median_iteration_ms", median(std::vector<double>(prog_.iteration_ms.begin(), prog_.iteration_ms.end()))},
          {"stage_ms_per_iteration", stage_ms_json(prog_)},
          {"model_bytes", m.file_bytes()},
          {"model_file_bytes", m.file_bytes()},  // what model.hbgs holds once this iteration is committed
          {"anchors", m.anchor_count},
          {"mean_gaussians_per_view", gaussians / double(r.views.size())},
          {"render_ms_median", r.render_ms_median},
          {"image_features", model::image_feature_mode_name(m.config.image_features)},
          {"background", a_.background},
          {"test_views", r.views.size()},
          {"isa", d_->kernels->isa},
          {"threads", d_->pool->num_threads()}};
}

nlohmann::json TrainRun::budget_json(int it) const {
  nlohmann::json j = {{"seconds", a_.time_budget},
                      {"seconds_used", prog_.train_seconds},
                      {"iteration_cap", a_.iterations},
                      {"predicted_iterations", planned_iterations_},
                      {"predictions", budget_ ? budget_->predictions() : 0},
                      {"schedule_progress", trainer_->schedule_progress()}};
  if (final_) j["iterations_fit"] = it;
  return j;
}

Status TrainRun::full_eval(int it) {
  if (!have_test_) return Status::Ok();
  const std::string method = "ours_" + std::to_string(it);
  std::unique_ptr<metrics::LpipsAlex> lpips;  // for this evaluation only (have_lpips_)
  if (have_lpips_) {
    std::string unused_note;
    Expected<std::unique_ptr<metrics::LpipsAlex>> loaded = load_lpips(a_.lpips_weights, a_.threads, &unused_note);
    if (!loaded.ok()) return loaded.status();
    lpips = std::move(loaded).value();
  }
  model::EvalOptions eo;
  eo.lpips = lpips.get();
  std::copy(trainer_->options().background.rgb, trainer_->options().background.rgb + 3, eo.render.background);
  eo.render_dir = (fs::path(a_.out) / "test" / method / "renders").string();
  nlohmann::json test_pose_report;
  std::vector<io::DatasetView> registered;
  if (a_.optimize_poses) GS_RETURN_IF_ERROR(registered_test_views(eo, &registered, &test_pose_report));
  Expected<model::EvalResult> r =
      model::evaluate_views(*trainer_, a_.optimize_poses ? pointers_to(registered) : d_->test_views, eo, d_->pool.get());
  if (!r.ok()) return r.status();
  nlohmann::json extra = eval_extra(it, *r);
  if (lpips) extra["lpips_backbone"] = metrics::LpipsAlex::kLabel;
  if (a_.time_budget > 0) extra["time_budget"] = budget_json(it);
  if (a_.optimize_poses) {
    extra["test_poses"] = "dataset poses mapped into the model's frame (Sim(3) of the training camera centres), then registered against the model";
    extra["test_pose_registration"] = test_pose_report;
  } else {
    extra["test_poses"] = a_.pose_noise_on == "train" ? "true (dataset) poses, not registered" : "noisy poses, not registered";
  }
  extra["poses"] = pose_json();
  std::string merge_note;
  GS_RETURN_IF_ERROR(write_eval_files(a_.out, method, *r, extra, &merge_note));
  if (!merge_note.empty()) note(merge_note);
  if (lpips && r->lpips < 0 && final_)
    note("LPIPS not computed: the test views are smaller than " + std::to_string(metrics::LpipsAlex::kMinSide) + " px a side");
  if (a_.eval_every > 0) add_psnr_row(it, r->psnr);
  final_eval_ = std::move(r).value();
  return Status::Ok();
}

Status TrainRun::commit() {
  std::error_code ec;
  const int it = trainer_->iteration();
  if (listed(it))
    GS_RETURN_IF_ERROR(model::save_model(trainer_->model(), (fs::path(a_.out) / ("model_" + std::to_string(it) + ".hbgs")).string()));
  auto next = [&](const char* name) { return (fs::path(a_.out) / (std::string(name) + kNextSuffix)).string(); };
  prog_.iteration = it;
  Status st = model::save_model(trainer_->model(), next(kModelFile));
  if (st.ok()) st = trainer_->save_checkpoint(next(kCheckpointFile));
  if (st.ok()) st = save_progress_to(next(kProgressFile), prog_);
  if (!st.ok()) {
    for (const char* n : {kModelFile, kCheckpointFile, kProgressFile}) fs::remove(next(n), ec);
    return st;
  }
  return commit_run_state(a_.out, it, dataset_abs_, model_options_, {kModelFile, kCheckpointFile, kProgressFile});
}

Status TrainRun::train() {
  if (!a_.resume && a_.eval_every > 0 && have_test_) {
    Status st = quick_psnr(0);
    if (st.ok()) st = write_psnr_files(a_.out, prog_.rows, title_);
    if (!st.ok()) return Status(st.code(), "evaluation at iteration 0: " + st.message());
  }
  const std::function<double()> clock = a_.clock ? a_.clock : [] { return platform::now_seconds(); };
  planned_iterations_ = a_.iterations;
  if (a_.time_budget > 0) {
    budget_ = std::make_unique<TimeBudget>(a_.time_budget, a_.iterations);
    // A resumed run continues the pace it measured (and the schedule its checkpoint holds).
    for (size_t i = 0; i < prog_.iteration_ms.size(); ++i) budget_->record(int(i) + 1, 1e-3 * prog_.iteration_ms[i]);
    planned_iterations_ = trainer_->options().iterations;
    if (!budget_->next_fits(prog_.train_seconds)) {
      note("the time budget of " + fixed(a_.time_budget, 1) + " s is spent (" + fixed(prog_.train_seconds, 1) +
           " s trained): no further iterations");
      return Status::Ok();
    }
  }
  // Stage timers stay on: about a thousand clock reads per step (two per tile of the forward tile
  // pass, a few per stage), well under 0.1 % of an iteration (docs/MODEL.md).
  trainer_->set_stage_times(&stage_times_);
  for (int it = trainer_->iteration() + 1; it <= a_.iterations; ++it) {
    model::IterationStats stats;
    const double t0 = clock(), c0 = platform::process_cpu_seconds();
    if (Status st = trainer_->step(&stats); !st.ok()) return at_iteration(it, st);
    const double dt = clock() - t0;
    prog_.train_seconds += dt;
    prog_.train_cpu_seconds += platform::process_cpu_seconds() - c0;
    prog_.iteration_ms.push_back(float(1e3 * dt));
    prog_.losses.push_back(float(stats.step.loss));
    for (int s = 0; s < kStageCount; ++s) prog_.stage_ms[s] += 1e-6 * double(stage_times_.ns[s]);
    prog_.stage_iterations += int(stage_times_.iterations);
    stage_times_.reset();
    if (stats.skipped_nonfinite) {
      ++prog_.skipped_steps;
      note("iteration " + std::to_string(it) + ": the loss or a gradient was NaN or infinite; the step was skipped (" +
           std::to_string(prog_.skipped_steps) + " so far)");
    }
    if (budget_) {
      if (Status st = steer_by_budget(it, dt); !st.ok()) return at_iteration(it, st);
    }
    final_ = it == a_.iterations || (budget_ && !budget_->next_fits(prog_.train_seconds));
    TrainEvent ev;
    ev.kind = TrainEvent::kIteration;
    ev.iteration = it;
    // 0 while a fresh time-budgeted run has not predicted its length yet.
    ev.iterations = final_ ? it : (budget_ && budget_->predictions() == 0 && resumed_from_ < 0) ? 0 : std::max(it, planned_iterations_);
    ev.stats = &stats;
    ev.last = final_;
    ev.budget_seconds = a_.time_budget;
    ev.remaining_seconds = remaining_seconds();
    say_(ev);
    if (Status st = after_step(it); !st.ok()) return at_iteration(it, st);
    if (final_) break;
  }
  return Status::Ok();
}

Status TrainRun::steer_by_budget(int it, double seconds) {
  budget_->record(it, seconds);
  if (!budget_->due(prog_.train_seconds)) return Status::Ok();
  const int total = budget_->predict(it, prog_.train_seconds);
  if (total == planned_iterations_) return Status::Ok();
  model::TrainOptions schedule = trainer_->options();
  set_run_length(a_, std::max(total, 1), &schedule);
  GS_RETURN_IF_ERROR(trainer_->retarget(schedule));
  planned_iterations_ = total;
  return Status::Ok();
}

// The evaluations, pose report, commit and PSNR files due after iteration it.
Status TrainRun::after_step(int it) {
  const bool full = final_ || listed(it);
  const bool quick = !full && a_.eval_every > 0 && have_test_ && it % a_.eval_every == 0;
  const bool save = full || (a_.checkpoint_every > 0 && it % a_.checkpoint_every == 0);
  Status out_st;
  if (final_) release_for_final_eval();
  if (full) {
    out_st = full_eval(it);
    last_full_ = it;
  }
  if (a_.optimize_poses && a_.eval_every > 0 && it % a_.eval_every == 0) {
    TrainEvent pe;
    pe.kind = TrainEvent::kPoseErrors;
    pe.iteration = it;
    pe.iterations = a_.iterations;
    pe.pose_errors = d_->errors(poses_of(trainer_->cameras()), true);
    say_(pe);
  }
  if (out_st.ok() && quick) out_st = quick_psnr(it);
  if (out_st.ok() && save) out_st = commit();
  if (out_st.ok() && (quick || (full && a_.eval_every > 0 && have_test_))) out_st = write_psnr_files(a_.out, prog_.rows, title_);
  return out_st;
}

Status TrainRun::finish() {
  const int final_it = trainer_->iteration();
  final_ = true;
  if (last_full_ != final_it) {
    release_for_final_eval();
    GS_RETURN_IF_ERROR(full_eval(final_it));
  }
  if (a_.optimize_poses)
    GS_RETURN_IF_ERROR(write_posed_model(a_.dataset, d_->train_names, poses_of(trainer_->cameras()),
                                         (fs::path(a_.out) / "refined_poses").string(), trainer_->model().frame));
  return Status::Ok();
}

void TrainRun::summarise(TrainRunSummary* summary) const {
  TrainRunSummary s;
  s.train_pose_input = d_->input_errors;
  s.train_pose_final = d_->errors(poses_of(trainer_->cameras()), true);
  s.run_dir = a_.out;
  s.model_path = model_path_;
  s.image_features = model::image_feature_mode_name(trainer_->model().config.image_features);
  s.iterations = trainer_->iteration();
  s.resumed_from = resumed_from_;
  s.have_test_views = have_test_;
  s.final_eval = final_eval_;
  s.train_seconds = prog_.train_seconds;
  s.median_iteration_ms = median(std::vector<double>(prog_.iteration_ms.begin(), prog_.iteration_ms.end()));
  s.skipped_steps = prog_.skipped_steps;
  s.time_budget = a_.time_budget;
  s.schedule_progress = trainer_->schedule_progress();
  for (int st = 0; st < kStageCount; ++st) s.stage_ms_per_iteration[st] = prog_.stage_ms_per_iteration(st);
  s.anchors = trainer_->model().anchor_count;
  s.train_views = d_->train_views.size();
  s.test_views = d_->test_views.size();
  s.model_bytes = trainer_->model().file_bytes();
  s.model_file_bytes = file_size_or_zero(model_path_);
  s.isa = d_->kernels->isa;
  s.threads = d_->pool->num_threads();
  for (const model::ViewMetrics& v : final_eval_.views) s.mean_gaussians += double(v.gaussians);
  if (!final_eval_.views.empty()) s.mean_gaussians /= double(final_eval_.views.size());
  *summary = std::move(s);
}

Status TrainRun::run(TrainRunSummary* summary) {
  GS_RETURN_IF_ERROR(check_arguments());
  GS_RETURN_IF_ERROR(open_run_folder());
  GS_RETURN_IF_ERROR(resolve_resume());
  GS_RETURN_IF_ERROR(check_before_session());
  GS_RETURN_IF_ERROR(prepare_session());
  GS_RETURN_IF_ERROR(start());
  GS_RETURN_IF_ERROR(train());
  GS_RETURN_IF_ERROR(finish());
  if (summary) summarise(summary);
  return Status::Ok();
}

Status train_run(const TrainRunOptions& options, const TrainProgressFn& progress, TrainRunSummary* summary) {
  TrainRun run(options, progress);
  return run.run(summary);
}

}  // namespace gs::jobs
