// SPDX-License-Identifier: MIT
// The posed models the jobs write: a training run with pose optimisation writes refined_poses/ and a
// batch registration registered/, each as COLMAP text and as transforms.json (nerfstudio's layout)
// holding the same poses and intrinsics, with paths that lead to the dataset's own images and
// masks; on a COLMAP dataset and on a NeRF-style one given as its .json file.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include "gs/io/colmap.h"
#include "gs/io/transforms.h"
#include "gs/jobs/pose_truth.h"
#include "gs/jobs/register.h"
#include "gs/jobs/train.h"
#include "gs/platform/file.h"
#include "support/run_command.h"

namespace {

namespace fs = std::filesystem;

using gs::test::run;

fs::path fresh(const std::string& name) { return gs::test::fresh_dir(GS_TEST_TMP, name); }

// Checks <dir>/transforms.json against <dir>/{cameras,images}.txt: every image once, with the same
// pose (1e-9: both come from the same double pose) and intrinsics, a file_path (and mask_path when
// `masks`) leading to an existing file, and `test_views` views in the test list.
void check_posed_folder(const fs::path& dir, size_t test_views, bool masks) {
  const std::string json = (dir / gs::jobs::kPosedTransformsJson).string();
  REQUIRE(gs::platform::file_exists(json));
  gs::Expected<gs::io::ColmapModel> model = gs::io::read_colmap_text(dir.string());
  REQUIRE_MESSAGE(model.ok(), model.status().to_string());
  gs::Expected<std::string> text = gs::platform::read_text_file(json);
  REQUIRE(text.ok());
  gs::io::TransformsFile file;
  REQUIRE(gs::io::parse_transforms_json(*text, json, &file).ok());
  REQUIRE(file.frames.size() == model->images.size());

  std::map<std::string, const gs::io::ColmapImage*> by_file;  // image file name -> COLMAP image
  for (const gs::io::ColmapImage& im : model->images) by_file[fs::path(im.name).filename().string()] = &im;
  for (const gs::io::TransformsFrame& f : file.frames) {
    const fs::path image = dir / f.file_path;
    CHECK_MESSAGE(fs::is_regular_file(image), image.string());
    CHECK(fs::path(f.file_path).is_relative());
    if (masks) CHECK_MESSAGE(fs::is_regular_file(dir / f.mask_path), (dir / f.mask_path).string());
    else CHECK(f.mask_path.empty());
    const auto it = by_file.find(image.filename().string());
    REQUIRE_MESSAGE(it != by_file.end(), f.file_path);
    const gs::io::ColmapImage& im = *it->second;
    double q[4], t[3];
    REQUIRE(gs::io::pose_from_transform_matrix(f.transform_matrix, q, t).empty());
    const gs::Pose a = gs::io::pose_from_colmap(q, t), b = gs::io::pose_from_colmap(im.qvec, im.tvec);
    for (int k = 0; k < 9; ++k) CHECK(a.R[k] == doctest::Approx(b.R[k]).epsilon(1e-6));
    for (int k = 0; k < 3; ++k) CHECK(std::abs(t[k] - im.tvec[k]) <= 1e-9);
    const gs::io::ColmapCamera* cam = nullptr;
    for (const gs::io::ColmapCamera& c : model->cameras)
      if (c.id == im.camera_id) cam = &c;
    REQUIRE(cam);
    gs::Expected<gs::io::TransformsIntrinsics> in = gs::io::transforms_intrinsics(*cam);
    if (!in.ok()) continue;  // a model transforms_intrinsics does not take (SIMPLE_RADIAL...): not in these scenes
    CHECK(*f.intrinsics.fl_x == *in->fl_x);
    CHECK(*f.intrinsics.fl_y == *in->fl_y);
    CHECK(*f.intrinsics.cx == *in->cx);
    CHECK(*f.intrinsics.cy == *in->cy);
    CHECK(*f.intrinsics.w == cam->width);
    CHECK(*f.intrinsics.h == cam->height);
  }
  REQUIRE(file.test_filenames);
  CHECK(file.test_filenames->size() == test_views);
  CHECK(file.train_filenames->size() == file.frames.size() - test_views);
}

gs::jobs::TrainRunOptions short_posed_run(const std::string& dataset, const std::string& out) {
  gs::jobs::TrainRunOptions o;
  o.dataset = dataset;
  o.out = out;
  o.iterations = 10;
  o.threads = 2;
  o.eval_every = 0;
  o.checkpoint_every = 0;
  o.save_at = "";
  o.pose_noise = "rot:1,trans:0.01";
  o.optimize_poses = true;
  return o;
}

}  // namespace

TEST_CASE("posed outputs: train --optimize-poses and register --views write transforms.json beside the COLMAP text (COLMAP dataset)") {
  const fs::path tmp = fresh("posed_colmap");
  const std::string scene = (tmp / "scene").string();
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + scene + " --width 64 --height 48 --views-arc 3 --views-orbit 3 --points 300 --seed 7") == 0);

  const gs::jobs::TrainRunOptions o = short_posed_run(scene, (tmp / "run").string());
  const gs::Status st = gs::jobs::train_run(o, nullptr, nullptr);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  check_posed_folder(tmp / "run" / "refined_poses", 1, false);

  gs::jobs::RegisterRunOptions r;
  r.input = o.out;
  r.views = "test";
  r.init_noise = "rot:5,trans:0.05,seed:1";
  r.downscale = 2;
  r.threads = 2;
  r.out = (tmp / "register").string();
  gs::jobs::RegisterViewsSummary summary;
  const gs::Status rst = gs::jobs::register_views(r, nullptr, &summary);
  REQUIRE_MESSAGE(rst.ok(), rst.to_string());
  check_posed_folder(tmp / "register" / "registered", 1, false);
  std::error_code ec;
  fs::remove_all(tmp, ec);
}

TEST_CASE("posed outputs: a NeRF-style dataset given as its .json file (masks, views named by their path)") {
  const fs::path tmp = fresh("posed_transforms");
  const std::string object = (tmp / "object").string();
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --object --out " + object + " --views 8 --width 48 --height 40 --points 200") == 0);
  // Without sparse/0 beside it the COLMAP model of the refined poses is made from the json's views.
  fs::remove_all(fs::path(object) / "sparse");

  const gs::jobs::TrainRunOptions o = short_posed_run((fs::path(object) / "transforms_train.json").string(), (tmp / "run").string());
  const gs::Status st = gs::jobs::train_run(o, nullptr, nullptr);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  check_posed_folder(tmp / "run" / "refined_poses", 1, true);
  gs::Expected<gs::io::ColmapModel> model = gs::io::read_colmap_text((tmp / "run" / "refined_poses").string());
  REQUIRE(model.ok());
  CHECK(model->images.size() == 8);
  CHECK(model->images.front().name.rfind("images/", 0) == 0);  // relative to the json's folder

  // One image registered without --camera: the dataset's one camera comes from the json.
  const gs::io::ColmapImage& view = model->images[1];
  char init[256];
  std::snprintf(init, sizeof init, "%.17g %.17g %.17g %.17g %.17g %.17g %.17g", view.qvec[0], view.qvec[1], view.qvec[2],
                view.qvec[3], view.tvec[0], view.tvec[1], view.tvec[2]);
  gs::jobs::RegisterRunOptions r;
  r.input = o.out;
  r.image = (fs::path(object) / view.name).string();
  r.init = init;
  r.threads = 2;
  gs::jobs::RegisterImageSummary single;
  const gs::Status rst = gs::jobs::register_image(r, &single);
  REQUIRE_MESSAGE(rst.ok(), rst.to_string());
  CHECK(single.intrinsics.fx == float(model->cameras.front().params[0]));
  CHECK(single.intrinsics.cx == float(model->cameras.front().params[2]));
  std::error_code ec;
  fs::remove_all(tmp, ec);
}

TEST_CASE("train --optimize-poses evaluates test views in the model's frame: mapped by the training centres' Sim(3), then registered") {
  const fs::path tmp = fresh("test_view_frame");
  const std::string scene = (tmp / "scene").string();
  REQUIRE(run(std::string(GS_HBGS_EXE) + " synth --out " + scene + " --width 96 --height 72 --views-arc 6 --views-orbit 6 --seed 3") == 0);
  // Noise on every view, test views too: their given poses are 2 degrees off, so the PSNR at the
  // dataset poses mixes pose error into the model's, and registration must take it out.
  gs::jobs::TrainRunOptions o = short_posed_run(scene, (tmp / "run").string());
  o.iterations = 300;
  o.pose_noise = "rot:2,trans:0.02,seed:5";
  o.pose_noise_on = "all";
  const gs::Status st = gs::jobs::train_run(o, nullptr, nullptr);
  REQUIRE_MESSAGE(st.ok(), st.to_string());
  std::ifstream in(tmp / "run" / "results.json");
  const nlohmann::json r = nlohmann::json::parse(in)["ours_300"];
  const nlohmann::json& t = r.at("test_pose_registration");
  MESSAGE("test PSNR at the dataset poses " << t.at("PSNR_at_dataset_poses").get<double>() << " dB, mapped "
                                            << t.at("PSNR_at_mapped_poses").get<double>() << " dB, registered " << r.at("PSNR").get<double>()
                                            << " dB; " << t.at("registered").get<int>() << " of " << r.at("test_views").get<int>()
                                            << " registered, moved " << t.at("registration_rotation_mean_deg").get<double>() << " degrees");
  CHECK(r.at("test_poses").get<std::string>().find("registered") != std::string::npos);
  CHECK(t.at("registered").get<int>() == r.at("test_views").get<int>());
  CHECK(t.at("registration_rotation_mean_deg").get<double>() > 0.5);  // the 2-degree noise was found and taken out
  CHECK(r.at("PSNR").get<double>() > t.at("PSNR_at_dataset_poses").get<double>() + 1.0);
  std::error_code ec;
  fs::remove_all(tmp, ec);
}
