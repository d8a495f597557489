// SPDX-License-Identifier: MIT
// libFuzzer harness: checkpoint.bin through Trainer::load_checkpoint, for a trainer set up once on a
// tiny in-memory scene (2 views of 16x12, 40 points). The checkpoint reader takes a path, so each
// input is written to a tmpfs scratch file; the first byte chooses the checksum fix-up (fuzz_util.h).
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "fuzz_util.h"
#include "gs/io/colmap.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/trainer.h"

namespace {

struct Fixture {
  std::vector<gs::io::DatasetView> views;
  std::vector<const gs::io::DatasetView*> ptrs;
  std::unique_ptr<gs::model::Trainer> trainer;

  Fixture() {
    views.resize(2);
    for (size_t v = 0; v < views.size(); ++v) {
      gs::io::DatasetView& d = views[v];
      d.name = "v" + std::to_string(v) + ".png";
      d.camera.intr = gs::PinholeIntrinsics{14, 14, 8, 6, 16, 12};
      d.camera.pose.R[0] = d.camera.pose.R[4] = d.camera.pose.R[8] = 1;
      d.camera.pose.t[0] = 0.1f * float(v);
      d.camera.pose.t[2] = 4;
      d.image.width = 16;
      d.image.height = 12;
      d.image.channels = 3;
      d.image.pixels.assign(16 * 12 * 3, uint8_t(60 + 40 * v));
      ptrs.push_back(&d);
    }
    std::vector<float> xyz;
    for (int i = 0; i < 40; ++i) xyz.insert(xyz.end(), {std::sin(float(i)), std::cos(1.3f * float(i)), 0.1f * float(i % 7)});
    gs::model::ModelConfig c;
    c.max_anchors = 64;
    c.max_gaussians = 640;
    gs::Expected<gs::model::HybridModel> m = gs::model::create_model(c, xyz.data(), 40, 4.0f, 1);
    if (!m.ok()) std::abort();
    gs::model::TrainOptions o;
    o.iterations = 1;
    gs::Expected<std::unique_ptr<gs::model::Trainer>> t = gs::model::Trainer::create(std::move(*m), ptrs, o, nullptr);
    if (!t.ok()) std::abort();
    trainer = std::move(*t);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static Fixture fixture;
  static const std::string path = gs::fuzz::scratch_path(".ckpt");
  const std::vector<uint8_t> b = gs::fuzz::with_checksum(data, size);
  if (!gs::fuzz::write_scratch(path, b.data(), b.size())) return 0;
  (void)fixture.trainer->load_checkpoint(path);
  return 0;
}
