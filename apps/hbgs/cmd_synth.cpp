// SPDX-License-Identifier: MIT
// `hbgs synth`: writes the built-in ray-traced ground-truth scene, or with --object an object
// capture (COLMAP + transforms.json, alpha or masks), as a dataset (via hbgs_synth), refusing to
// overwrite an existing dataset unless --force is given; or a camera path through either scene as
// frames with its true poses (--path-frames: the sweep for ingestion, --trajectory: the hand-held
// test trajectory for tracking, with a video).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

#include "common.h"

#ifdef HBGS_HAVE_SYNTH
#include "hbgs/synth.h"
#endif

namespace hbgs::cli {
namespace {

struct SynthArgs {
  std::string out;
  uint64_t seed = 1;
  int width = 256, height = 192;
  int views_arc = 16, views_orbit = 24;
  int points = 6000;
  int threads = 0;
  bool force = false;
  bool quiet = false;
  int path_frames = 0;  // > 0: render a camera path (frames + true poses) instead of the dataset
  double path_sweep = 100.0;
  bool trajectory = false;  // the hand-held test trajectory instead of the dataset
  int frames = 300;
  double fps = 30.0;
  std::string background = "white";  // --trajectory --object: the colour behind the subject
  int samples = 0;                    // samples per pixel axis; 0: the dataset's (2, --object: 4)
  bool no_video = false;
  std::string ffmpeg = "ffmpeg";
  bool object = false;  // the object capture instead of the scene
  int views = 48;
  std::string object_background = "transparent";
  bool size_given = false, points_given = false;
  std::string camera = "pinhole";  // the dataset's lens: pinhole or fisheye
};

#ifdef HBGS_HAVE_SYNTH

namespace fs = std::filesystem;

// An existing dataset in out is refused without --force. With --force, the binary model files of
// a previous dataset are removed: synth writes the text model, and load_dataset prefers .bin, so a
// stale .bin set would silently shadow the new scene.
int prepare_output(const SynthArgs& a) {
  const fs::path root(a.out);
  std::error_code ec;
  if (fs::exists(root, ec) && !fs::is_directory(root, ec))
    return fail("synth", a.out + " exists and is not a directory");
  const fs::path sparse = root / "sparse" / "0", images = root / "images";
  const bool has_dataset = fs::exists(sparse, ec) || fs::exists(images, ec) || fs::exists(root / "transforms_train.json", ec);
  if (has_dataset && !a.force)
    return fail("synth", a.out + " already holds a dataset (" + (fs::exists(sparse, ec) ? sparse : images).string() +
                             " exists); pass --force to overwrite it");
  if (has_dataset) {
    for (const char* name : {"cameras.bin", "images.bin", "points3D.bin"}) {
      const fs::path p = sparse / name;
      if (fs::exists(p, ec) && !fs::remove(p, ec))
        return fail("synth", "cannot remove the stale " + p.string() + ": " + ec.message());
    }
    // The object capture's images change extension with its background (png / jpg) and masks/ is
    // searched by name: a previous capture's files would be read in place of the new ones.
    if (a.object) {
      for (const fs::path& p : {root / "images", root / "masks", root / "transforms_train.json", root / "transforms_test.json"}) {
        fs::remove_all(p, ec);
        if (ec) return fail("synth", "cannot remove the previous " + p.string() + ": " + ec.message());
      }
    }
  }
  return kExitOk;
}

// `--object`: the object capture.
int run_synth_object(const SynthArgs& a) {
  if (int rc = prepare_output(a); rc != kExitOk) return rc;
  hbgs::synth::ObjectOptions o;
  o.seed = a.seed;
  if (a.size_given) o.width = a.width, o.height = a.height;
  if (a.points_given) o.num_points = a.points;
  o.views = a.views;
  o.threads = a.threads;
  o.verbose = !a.quiet;
  if (a.object_background == "cluttered") o.background = hbgs::synth::ObjectOptions::Background::kCluttered;
  gs::Expected<hbgs::synth::ObjectSummary> summary = hbgs::synth::generate_object(o, a.out);
  if (!summary.ok()) return fail("synth", summary.status().to_string());
  const fs::path root(a.out);
  std::printf("hbgs synth --object: %d views (%d test) of %dx%d, %s background, %d sparse points, seed %llu, %.2f s "
              "(rendering %.2f s)\n",
              summary->num_views, summary->num_test_views, o.width, o.height, a.object_background.c_str(), summary->num_points,
              static_cast<unsigned long long>(a.seed), summary->seconds, summary->render_seconds);
  std::printf("  images:     %s\n  masks:      %s\n  model:      %s\n  transforms: %s, %s\n",
              (root / "images").string().c_str(), (root / "masks").string().c_str(), (root / "sparse" / "0").string().c_str(),
              (root / "transforms_train.json").string().c_str(), (root / "transforms_test.json").string().c_str());
  return kExitOk;
}

// A camera path's files in out are refused without --force; with it they are removed first (a
// longer earlier path would leave frames behind that a video pattern would read).
int prepare_path_output(const SynthArgs& a) {
  const fs::path root(a.out);
  std::error_code ec;
  const char* const names[] = {hbgs::synth::kPathFramesDir, hbgs::synth::kPathTruePosesDir, hbgs::synth::kPathTumFile,
                                hbgs::synth::kPathJsonFile, hbgs::synth::kPathVideoFile};
  for (const char* name : names)
    if (fs::exists(root / name, ec) && !a.force)
      return fail("synth", (root / name).string() + " already exists; pass --force to overwrite it");
  for (const char* name : names) {
    fs::remove_all(root / name, ec);
    if (ec) return fail("synth", "cannot remove the previous " + (root / name).string() + ": " + ec.message());
  }
  return kExitOk;
}

void print_path_files(const fs::path& root, const hbgs::synth::PathSummary& s, bool video_asked) {
  std::printf("  frames:     %s\n", (root / hbgs::synth::kPathFramesDir).string().c_str());
  if (s.video_written) std::printf("  video:      %s\n", (root / hbgs::synth::kPathVideoFile).string().c_str());
  else if (video_asked) std::printf("  video:      none (%s)\n", s.video_note.c_str());
  std::printf("  true poses: %s (TUM), %s (COLMAP)\n  path:       %s\n", (root / hbgs::synth::kPathTumFile).string().c_str(),
              (root / hbgs::synth::kPathTruePosesDir).string().c_str(), (root / hbgs::synth::kPathJsonFile).string().c_str());
}

// `--path-frames N`: frames of a hand-held style camera path for video-ingestion tests.
int run_synth_path(const SynthArgs& a) {
  if (int rc = prepare_path_output(a); rc != kExitOk) return rc;
  hbgs::synth::PathOptions o;
  o.seed = a.seed;
  o.width = a.width;
  o.height = a.height;
  o.frames = a.path_frames;
  o.sweep_deg = a.path_sweep;
  o.threads = a.threads;
  Stopwatch sw;
  const gs::Expected<hbgs::synth::PathSummary> summary = hbgs::synth::generate_path(o, a.out);
  if (!summary.ok()) return fail("synth", summary.status().to_string());
  std::printf("hbgs synth: %d path frames of %dx%d (%.0f degree sweep), seed %llu, %.2f s\n", o.frames, o.width,
              o.height, o.sweep_deg, static_cast<unsigned long long>(a.seed), sw.seconds());
  print_path_files(fs::path(a.out), *summary, false);
  return kExitOk;
}

// `--trajectory [--object]`: the hand-held test trajectory (frames, video, true poses).
int run_synth_trajectory(const SynthArgs& a) {
  hbgs::synth::PathOptions o;
  o.kind = hbgs::synth::PathOptions::Kind::kHandheld;
  o.scene = a.object ? hbgs::synth::PathOptions::SceneKind::kObject : hbgs::synth::PathOptions::SceneKind::kScene;
  o.seed = a.seed;
  o.width = a.object && !a.size_given ? 200 : a.width;
  o.height = a.object && !a.size_given ? 200 : a.height;
  o.frames = a.frames;
  o.fps = a.fps;
  o.samples_per_axis = a.samples > 0 ? a.samples : a.object ? 4 : 2;  // as the datasets are rendered
  if (a.object) {
    const gs::Expected<gs::model::Background> bg = gs::model::parse_background(a.background);
    if (!bg.ok()) return fail("synth", "--background: " + bg.status().message());
    if (bg->random) return fail("synth", "--background: frames need one colour (the one the model renders on), not random");
    std::copy(bg->rgb, bg->rgb + 3, o.background);
  }
  o.video = !a.no_video;
  o.ffmpeg = a.ffmpeg;
  o.threads = a.threads;
  o.verbose = !a.quiet;
  if (const gs::Status st = hbgs::synth::validate_path(o); !st.ok()) return fail("synth", st.message());
  if (int rc = prepare_path_output(a); rc != kExitOk) return rc;
  const gs::Expected<hbgs::synth::PathSummary> summary = hbgs::synth::generate_path(o, a.out);
  if (!summary.ok()) return fail("synth", summary.status().to_string());
  const hbgs::synth::PathEvents& ev = summary->events;
  std::printf("hbgs synth --trajectory: %d frames of %dx%d at %g fps (%.1f s) through the %s, seed %llu; pan at frames "
              "%d-%d (%g degrees at %g degrees/s), cut at frame %d; %.2f s (rendering %.2f s, video %.2f s)\n",
              o.frames, o.width, o.height, o.fps, o.frames / o.fps,
              a.object ? ("object capture's subject on " + a.background).c_str() : "built-in scene",
              static_cast<unsigned long long>(a.seed), ev.pan_first, ev.pan_last, o.pan_deg, o.pan_speed_deg_s, ev.cut,
              summary->seconds, summary->render_seconds, summary->video_seconds);
  if (!summary->video_note.empty()) std::fprintf(stderr, "hbgs synth: %s\n", summary->video_note.c_str());
  print_path_files(fs::path(a.out), *summary, o.video);
  return kExitOk;
}

int run_synth(const SynthArgs& a) {
  if (a.object && a.path_frames > 0) return fail("synth", "--object and --path-frames exclude each other");
  if (a.trajectory && a.path_frames > 0) return fail("synth", "--trajectory and --path-frames exclude each other");
  if (a.trajectory && a.object_background != "transparent")
    return fail("synth", "--trajectory --object renders the subject alone on --background; --object-background " +
                             a.object_background + " is not supported");
  if (a.camera != "pinhole" && (a.trajectory || a.object || a.path_frames > 0))
    return fail("synth", "--camera " + a.camera + " applies to the built-in scene's dataset only (not --object, --trajectory or --path-frames)");
  if (a.trajectory) return run_synth_trajectory(a);
  if (a.object) return run_synth_object(a);
  if (a.path_frames > 0) return run_synth_path(a);
  if (int rc = prepare_output(a); rc != kExitOk) return rc;
  hbgs::synth::SynthOptions o;
  o.seed = a.seed;
  o.width = a.width;
  o.height = a.height;
  o.arc_views = a.views_arc;
  o.orbit_views = a.views_orbit;
  o.num_points = a.points;
  o.threads = a.threads;
  o.verbose = !a.quiet;
  if (a.camera == "fisheye") o.camera = hbgs::synth::SynthOptions::Camera::kFisheye;
  gs::Expected<hbgs::synth::SynthSummary> summary = hbgs::synth::generate_scene(o, a.out);
  if (!summary.ok()) return fail("synth", summary.status().to_string());

  const fs::path root(a.out);
  std::printf("hbgs synth: %d views (%d arc + %d orbit) of %dx%d, %d sparse points, seed %llu, %.2f s\n",
              summary->num_views, a.views_arc, a.views_orbit, a.width, a.height, summary->num_points,
              static_cast<unsigned long long>(a.seed), summary->seconds);
  if (o.camera == hbgs::synth::SynthOptions::Camera::kFisheye)
    std::printf("  camera: 180-degree equidistant fisheye (OPENCV_FISHEYE, f = %.4f, k1..k4 = 0)\n",
                hbgs::synth::fisheye_focal(a.width));
  std::printf("  images: %s\n  model:  %s\n", (root / "images").string().c_str(),
              (root / "sparse" / "0").string().c_str());
  return kExitOk;
}

#else

int run_synth(const SynthArgs&) { return fail("synth", "hbgs was built without Embree; synth is unavailable"); }

#endif

}  // namespace

Command add_synth_command(CLI::App& parent) {
  auto args = std::make_shared<SynthArgs>();
  CLI::App* sub = parent.add_subcommand("synth", "Write the built-in ray-traced test scene as a COLMAP dataset");
  sub->add_option("--out", args->out, "Output dataset folder (gets images/ and sparse/0/)")->required();
  sub->add_option("--seed", args->seed, "Scene seed (layout, textures, camera jitter, points)")->capture_default_str();
  CLI::Option* width = sub->add_option("--width", args->width, "Image width, pixels (--object: 200)")
                           ->capture_default_str()
                           ->check(CLI::Range(1, 16384));
  CLI::Option* height = sub->add_option("--height", args->height, "Image height, pixels (--object: 200)")
                            ->capture_default_str()
                            ->check(CLI::Range(1, 16384));
  sub->add_option("--views-arc", args->views_arc, "Views on the forward-facing arc")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  sub->add_option("--views-orbit", args->views_orbit, "Views on the full orbit")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  CLI::Option* points = sub->add_option("--points", args->points, "Sparse SfM points to write (--object: 5000, on the object)")
                            ->capture_default_str()
                            ->check(CLI::Range(0, 10000000));
  sub->add_option("--threads", args->threads, "Worker threads (0: all CPUs; output does not depend on it)")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  sub->add_option("--path-frames", args->path_frames,
                  "Instead of the dataset, render this many frames along a hand-held style camera path "
                  "(OUT/frames/, true poses in OUT/true_poses/), e.g. to encode as a test video")
      ->check(CLI::Range(0, 100000));
  sub->add_option("--path-sweep", args->path_sweep, "Azimuth the path sweeps, degrees")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 360.0));
  sub->add_flag("--trajectory", args->trajectory,
                "Instead of the dataset, a hand-held test trajectory through the scene (with --object, through the object "
                "capture's subject on --background) for tracking: --frames frames at --fps with hand shake, one 60 degree "
                "pan at 60 degrees/s and one cut to a distant viewpoint, at the dataset's size (256x192, --object: "
                "200x200); writes OUT/frames/, OUT/video.mp4 (ffmpeg, H.264), the true poses as OUT/true_trajectory.txt "
                "(TUM) and OUT/true_poses/ (COLMAP), and OUT/trajectory.json (fps, pan frames, cut frame, scene)");
  sub->add_option("--frames", args->frames, "--trajectory: number of frames (at least ~8 s of them)")
      ->capture_default_str()
      ->check(CLI::Range(2, 100000));
  sub->add_option("--fps", args->fps, "--trajectory: frames per second")->capture_default_str()->check(CLI::Range(1.0, 1000.0));
  sub->add_option("--background", args->background,
                  "--trajectory --object: the colour behind the subject, the one the model was trained on "
                  "(black, white or R,G,B)")
      ->capture_default_str()
      ->check(background_validator());
  sub->add_option("--samples", args->samples,
                  "--trajectory: anti-aliasing samples per pixel axis (default: the dataset's, 2, --object: 4)")
      ->check(CLI::Range(1, 16));
  sub->add_flag("--no-video", args->no_video, "--trajectory: write the frames and poses only, no video.mp4");
  sub->add_option("--ffmpeg", args->ffmpeg, "--trajectory: the ffmpeg program that encodes the video")->capture_default_str();
  sub->add_flag("--object", args->object,
                "Instead of the scene, an object capture: a small textured object on a pedestal seen from cameras on the "
                "upper hemisphere (three rings, 360 degrees), written as a COLMAP dataset (images/, masks/, sparse/0) and "
                "as transforms_train.json / transforms_test.json (every 8th view is a test view)");
  sub->add_option("--views", args->views, "--object: number of views")->capture_default_str()->check(CLI::Range(3, 100000));
  sub->add_option("--object-background", args->object_background,
                  "--object: transparent (RGBA PNG images, alpha = coverage) or cluttered (RGB JPEG images of the object "
                  "on a textured, cluttered background; masks/ mark the object)")
      ->capture_default_str()
      ->check(CLI::IsMember({"transparent", "cluttered"}));
  sub->add_option("--camera", args->camera,
                  "The dataset's lens: pinhole (PINHOLE, f = 0.9 width) or fisheye (a 180-degree equidistant fisheye, "
                  "OPENCV_FISHEYE with f = width / pi and k1..k4 = 0: 90 degrees from the axis at half the width from the "
                  "centre; corners outside that circle black). Same seed, same poses: the default synth is its pinhole "
                  "twin (give the fisheye 6x the twin's width for the twin's detail, e.g. 1536x1152 for 256x192)")
      ->capture_default_str()
      ->check(CLI::IsMember({"pinhole", "fisheye"}));
  sub->add_flag("--force", args->force,
                "Overwrite an existing dataset in --out (with --object, its images/, masks/ and transforms files are "
                "removed first)");
  sub->add_flag("-q,--quiet", args->quiet, "No progress output, only the summary");
  return {sub, [args, width, height, points] {
            args->size_given = width->count() > 0 || height->count() > 0;
            args->points_given = points->count() > 0;
            if (args->object && args->size_given && (width->count() == 0 || height->count() == 0))
              return fail("synth", "--object: give both --width and --height (default 200x200)");
            return run_synth(*args);
          }};
}

}  // namespace hbgs::cli
