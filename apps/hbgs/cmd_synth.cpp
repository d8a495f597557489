// SPDX-License-Identifier: MIT
// `hbgs synth`: writes the built-in ray-traced ground-truth scene as a COLMAP dataset (via
// hbgs_synth), refusing to overwrite an existing dataset unless --force is given.
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
  const bool has_dataset = fs::exists(sparse, ec) || fs::exists(images, ec);
  if (has_dataset && !a.force)
    return fail("synth", a.out + " already holds a dataset (" + (fs::exists(sparse, ec) ? sparse : images).string() +
                             " exists); pass --force to overwrite it");
  if (has_dataset) {
    for (const char* name : {"cameras.bin", "images.bin", "points3D.bin"}) {
      const fs::path p = sparse / name;
      if (fs::exists(p, ec) && !fs::remove(p, ec))
        return fail("synth", "cannot remove the stale " + p.string() + ": " + ec.message());
    }
  }
  return kExitOk;
}

int run_synth(const SynthArgs& a) {
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
  gs::Expected<hbgs::synth::SynthSummary> summary = hbgs::synth::generate_scene(o, a.out);
  if (!summary.ok()) return fail("synth", summary.status().to_string());

  const fs::path root(a.out);
  std::printf("hbgs synth: %d views (%d arc + %d orbit) of %dx%d, %d sparse points, seed %llu, %.2f s\n",
              summary->num_views, a.views_arc, a.views_orbit, a.width, a.height, summary->num_points,
              static_cast<unsigned long long>(a.seed), summary->seconds);
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
  sub->add_option("--width", args->width, "Image width, pixels")->capture_default_str()->check(CLI::Range(1, 16384));
  sub->add_option("--height", args->height, "Image height, pixels")->capture_default_str()->check(CLI::Range(1, 16384));
  sub->add_option("--views-arc", args->views_arc, "Views on the forward-facing arc")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  sub->add_option("--views-orbit", args->views_orbit, "Views on the full orbit")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000));
  sub->add_option("--points", args->points, "Sparse SfM points to write")->capture_default_str()->check(CLI::Range(0, 10000000));
  sub->add_option("--threads", args->threads, "Worker threads (0: all CPUs; output does not depend on it)")
      ->capture_default_str()
      ->check(CLI::Range(0, 4096));
  sub->add_flag("--force", args->force, "Overwrite an existing dataset in --out");
  sub->add_flag("-q,--quiet", args->quiet, "No progress output, only the summary");
  return {sub, [args] { return run_synth(*args); }};
}

}  // namespace hbgs::cli
