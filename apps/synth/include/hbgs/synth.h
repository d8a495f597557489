// SPDX-License-Identifier: MIT
// `hbgs synth`: the built-in ground-truth scene. A seeded procedural scene (textured ground plane
// plus a few textured meshes) is ray-traced with Embree 3 into a COLMAP dataset whose poses,
// intrinsics and sparse points are exactly consistent with the rendered images.
//
// World frame: right-handed, metres, z up, ground plane z = 0; the objects sit around the origin.
// Cameras follow COLMAP/hbgs: x_cam = R x_world + t, x right, y down, z forward, pixel centres at
// (i + 0.5, j + 0.5), u = fx x/z + cx, v = fy y/z + cy.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "gs/camera.h"
#include "gs/io/image.h"
#include "gs/status.h"

namespace hbgs::synth {

struct SynthOptions {
  uint64_t seed = 1;          // selects object placement, textures, camera jitter and points
  int width = 256;            // image size, pixels
  int height = 192;
  int arc_views = 16;         // forward-facing arc (~80 degrees) in front of the scene
  int orbit_views = 24;       // full orbit at a higher elevation
  int num_points = 6000;      // sparse SfM points written to points3D.txt
  float point_noise = 0.002f; // std-dev of the Gaussian noise added to each point, world units
  bool verbose = false;       // progress on stderr
  int samples_per_axis = 2;   // anti-aliasing: samples_per_axis^2 jittered rays per pixel
  int threads = 0;            // worker threads; 0 = all hardware threads (output never depends on it)
  // The lens. kPinhole: the PINHOLE camera below. kFisheye (`hbgs synth --camera fisheye`): a
  // 180-degree equidistant fisheye, written as COLMAP's OPENCV_FISHEYE with k1 = k2 = k3 = k4 = 0:
  // fx = fy = width / pi, cx = width / 2, cy = height / 2, so theta = 90 degrees from the axis lies
  // on the circle of radius width / 2 about the centre (through the middles of the left and right
  // edges): 180 degrees across the width, 180 height / width degrees across the height; the corners
  // outside that circle see nothing and are black. Same seed, same poses (and scene) as the pinhole
  // dataset of any size: the pinhole twin of a fisheye dataset is the default synth with the same
  // seed. The fisheye's centre detail is a pinhole's of focal width / pi, so it needs more pixels
  // than the twin for the twin's detail: 6x the twin's width (1536x1152 for the 256x192 twin,
  // focal 488.9 against 230.5) trains to the twin's test PSNR within noise, 4x (1024x768, focal
  // 325.9) loses 0.8 dB to the resampling's blur (README "Fisheye cameras").
  enum class Camera { kPinhole, kFisheye } camera = Camera::kPinhole;
};

struct SynthSummary {
  int num_views;
  int num_points;  // fewer than requested only if the scene could not supply enough visible points
  double seconds;  // wall time of generate_scene
};

// Writes out_dir/images/NNNN.png and out_dir/sparse/0/{cameras,images,points3D}.txt.
// Views are named in order: the arc views first (0000 .. arc_views-1), then the orbit views.
// Rig: the arc spans 80 degrees on the -y side, ~4.6 m from the layout centre (0.1, 0.2, 0.45) at
// ~16 degrees elevation; the orbit is a full circle ~5 m out at ~34 degrees; every camera looks at
// the centre, with a few centimetres of seeded jitter in position and look-at point.
// Sparse points: surface hits of seeded pixel-centre rays plus N(0, point_noise) noise, coloured
// by the rendered pixel, each with a track of every view that sees it (>= 2 views when there are
// two or more) and the exact projections stored as POINTS2D.
// One shared PINHOLE camera: fx = fy = 0.9 * width rounded to 1/4 px (exact in float),
// cx = width / 2, cy = height / 2 (kFisheye: the OPENCV_FISHEYE camera above; the sparse points'
// POINTS2D are its exact projections). Identical options give byte-identical files.
gs::Expected<SynthSummary> generate_scene(const SynthOptions& options, const std::string& out_dir);

// The cameras generate_scene uses for these options (intrinsics + pose, in view order); empty if
// the options are invalid. kFisheye: intr holds the pinhole camera of that size (the poses are the
// fisheye's; its lens is fisheye_focal's). The poses are exactly those gs::io::pose_from_colmap recovers from the
// written qvec/tvec, and the images are rendered with them.
std::vector<gs::Camera> make_cameras(const SynthOptions& options);
// The equidistant focal length of a kFisheye dataset of this width (width / pi), pixels.
double fisheye_focal(int width);

// Camera paths through the synth scenes, rendered as video frames with their true poses.
//
// kSweep (`hbgs synth --path-frames N`): a continuous path through the built-in scene, like a
// hand-held phone video: the camera sweeps `sweep_deg` of azimuth in front of the scene (centred on
// the -y side) while its height and distance drift smoothly and it looks at a slowly wandering point
// near the scene centre. Used to test video ingestion end to end, where the recovered poses are
// compared with these.
//
// kHandheld (`hbgs synth --trajectory`, with `--object` through the object capture's scene): a test
// trajectory for tracking, at `fps` frames per second. The camera walks slowly (at most ~3 degrees
// per second of azimuth about the scene centre, a few degrees of elevation and 3 % of distance
// drifting) while looking near the centre, with hand shake: smooth seeded wobble of 2 mm RMS per
// axis in position and 0.08 degrees RMS per axis in rotation (0.14 degrees RMS in all, peaks of
// about 0.3), each axis a sum of three sinusoids of 0.5-3 Hz, so smooth at 30 fps.
// Events, in this order:
//   - a slow turn (2.5 s) of the view direction to pan_deg / 2 right of the centre,
//   - the pan: a turn of pan_deg about the vertical through the camera at pan_speed_deg_s (speed
//     ramps of 0.1 s at both ends), from pan_deg / 2 right to pan_deg / 2 left of the centre,
//   - a slow turn (2.5 s) back to the centre,
//   - the cut: from frame cut - 1 to frame cut the camera jumps to a distant viewpoint (the other
//     side of the scene, higher: the built-in scene's orbit, the object capture's top ring) and the
//     path continues smoothly from there to the end.
// The pan starts at 0.3 of the duration (or once the first turn fits), the cut at 0.6 of it (or
// once the pan, the turn back and 0.5 s have passed); at least 1 s follows the cut, so a hand-held
// path needs about 8 s (237 frames at 30 fps with the default pan).
// Built-in scene: the walk is ~4.5 m from the layout centre at ~17 degrees elevation on the -y side
// (the dataset's arc), after the cut ~5 m out at ~30 degrees on the +y side (its orbit). Object:
// at the object capture's camera distance, first at the middle ring's 35 degrees elevation (seeded
// azimuth), after the cut at the top ring's 60 degrees on the opposite side.
// The frames are rendered from the same seeded scene as generate_scene / generate_object with the
// same seed (so a model trained on that dataset is valid for them), at the same anti-aliasing by
// default; the object's subject (no background geometry) is composited on `background` with
// gs::io::composite_rgb8 (the composite training and evaluation compare renders with): pick the
// colour the model was trained on (`hbgs train --background`, white for the object captures in
// these docs).
struct PathOptions {
  enum class Kind { kSweep, kHandheld };
  enum class SceneKind { kScene, kObject };  // generate_scene's scene, or generate_object's subject
  Kind kind = Kind::kSweep;
  SceneKind scene = SceneKind::kScene;       // kSweep: kScene only
  uint64_t seed = 1;         // the scene (same seeds as SynthOptions / ObjectOptions) and the shake
  int width = 320, height = 240;
  int frames = 90;
  double fps = 30.0;         // frame i is at time i / fps (the TUM file; kHandheld's speeds)
  double sweep_deg = 100.0;  // kSweep
  double pan_deg = 60.0, pan_speed_deg_s = 60.0;  // kHandheld
  float background[3] = {1, 1, 1};  // kObject: the colour behind the subject, in [0, 1]
  int samples_per_axis = 2;
  int threads = 0;           // 0 = all hardware threads (the output does not depend on it)
  bool video = false;        // also encode video.mp4 with the ffmpeg command line
  std::string ffmpeg = "ffmpeg";  // the program (looked up on PATH)
  bool verbose = false;      // progress on stderr
};

// Frame indices of the events of a kHandheld path (-1 for kSweep).
struct PathEvents {
  int pan_first = -1, pan_last = -1;  // frames whose time lies within the pan (its speed > 0)
  int cut = -1;                       // the first frame after the jump
};

struct PathSummary {
  int frames = 0;
  PathEvents events;
  double render_seconds = 0;  // ray tracing and PNG writing
  double video_seconds = 0;   // ffmpeg
  double seconds = 0;         // wall time of generate_path
  bool video_written = false;
  std::string video_note;     // why the video was skipped (ffmpeg not found, odd image size), else empty
};

// Checks the options (a hand-held path too short for its pan and cut names the frames it needs).
gs::Status validate_path(const PathOptions& options);
// Cameras of the path, in frame order; empty if the options are invalid.
std::vector<gs::Camera> make_path_cameras(const PathOptions& options);
// The events of the path (all -1 if the options are invalid or the path is a sweep).
PathEvents path_events(const PathOptions& options);
// Writes out_dir/frames/frame_000000.png ..., the true poses as a COLMAP text model in
// out_dir/true_poses/ (images named like the frames, no points) and as a TUM trajectory
// out_dir/true_trajectory.txt (timestamps i / fps), out_dir/trajectory.json (the path's kind, fps,
// frame count, size and intrinsics, the pan's frames and the cut's frame, the scene: kind, seed,
// background, the radius of the camera centres of that scene's default dataset's training views,
// the files), and with options.video out_dir/video.mp4: H.264 (libx264, CRF 18, yuv420p tagged
// BT.601 limited range, one encoder thread so the file does not depend on the thread count) at
// fps, by the ffmpeg command line (a phone video's kind of loss: about 31 dB against the frames,
// most of it the 4:2:0 chroma). Without ffmpeg on PATH, or for an odd width or height (4:2:0 needs even sides), the video
// is skipped and video_note says why; an ffmpeg that fails is an error with its output.
// Identical options give identical files.
gs::Expected<PathSummary> generate_path(const PathOptions& options, const std::string& out_dir);

// File names generate_path writes inside out_dir.
inline constexpr const char* kPathFramesDir = "frames";
inline constexpr const char* kPathTruePosesDir = "true_poses";
inline constexpr const char* kPathTumFile = "true_trajectory.txt";
inline constexpr const char* kPathJsonFile = "trajectory.json";
inline constexpr const char* kPathVideoFile = "video.mp4";

// `hbgs synth --object`: an object capture. The subject (a checkered pedestal, radius 0.5 m and
// 0.1 m high on z = 0, holding five small textured shapes; inside the sphere of radius
// kObjectRadius around kObjectCentre) is ray-traced from cameras on the upper hemisphere: `views`
// cameras in three rings (elevations 15, 35 and 60 degrees; a third of the views each, the top ring
// gets the remainder), 360 degrees of azimuth each, every ring turned by a seeded phase, looking at
// the centre with a few millimetres of seeded jitter from 1.1 x the distance at which the bounding
// sphere touches the narrower side of the image (1.29 m for a square image), so the whole subject
// is inside every image. The shared PINHOLE camera is the scene's (fx = fy = 0.9 width rounded to 1/4 px, principal
// point centred).
//
// kTransparent (default): images/NNNN.png are RGBA with straight alpha = the fraction of each
// pixel's samples_per_axis^2 jittered samples that hit the subject (0 on the background), RGB = the
// mean colour of those samples (0 where alpha is 0); masks/NNNN.png repeat the alpha (same-name
// masks). kCluttered: the subject stands on a textured ground among clutter (beyond the cameras,
// so never in front of the subject, and too low to shadow it) under the sky; images/NNNN.jpg are
// the RGB composite (JPEG quality 95) and masks/NNNN.jpg.png the subject's coverage (COLMAP's mask
// naming).
//
// Both write the COLMAP model in sparse/0 (exact poses; `num_points` sparse points on the subject's
// surface with their tracks, like generate_scene) and the same views as NeRF-style
// transforms_train.json / transforms_test.json (every 8th view by name, index 0, 8, ..., in the test
// file, as hbgs splits the COLMAP model): file_path "./images/NNNN" without extension, fl_x, fl_y,
// cx, cy, w, h and camera_angle_x, transform_matrix = the OpenGL camera-to-world of the same pose
// (gs::io::write_transforms_json, "camera_model" PINHOLE), and for kCluttered each frame's
// "mask_path". No point cloud is named in them: hbgs initialises such a dataset with random points
// (like NeRF's synthetic scenes).
constexpr double kObjectCentre[3] = {0.0, 0.0, 0.25};
constexpr double kObjectRadius = 0.57;

struct ObjectOptions {
  uint64_t seed = 1;       // object jitter, textures, camera jitter, points
  int width = 200;         // image size, pixels
  int height = 200;
  int views = 48;          // cameras (every 8th is a test view)
  int num_points = 5000;   // sparse points on the subject's surface, sparse/0/points3D.txt
  float point_noise = 0.001f;  // std-dev of the Gaussian noise added to each point, metres
  enum class Background { kTransparent, kCluttered } background = Background::kTransparent;
  int samples_per_axis = 4;  // anti-aliasing and alpha resolution: samples_per_axis^2 samples per pixel
  int threads = 0;           // 0 = all hardware threads (the output does not depend on it)
  bool verbose = false;      // progress on stderr
};

struct ObjectSummary {
  int num_views = 0, num_test_views = 0;
  int num_points = 0;
  double render_seconds = 0;  // ray tracing
  double seconds = 0;         // wall time of generate_object
};

// Writes the object capture into out_dir (images/, masks/, sparse/0/, transforms_train.json,
// transforms_test.json); identical options give byte-identical files.
gs::Expected<ObjectSummary> generate_object(const ObjectOptions& options, const std::string& out_dir);
// The cameras generate_object uses (view order = name order); empty if the options are invalid.
std::vector<gs::Camera> make_object_cameras(const ObjectOptions& options);

// A closest-hit query result.
struct SceneHit {
  double t = 0;                 // ray parameter: position = origin + t * dir (metres if |dir| = 1)
  double position[3] = {0, 0, 0};
  double normal[3] = {0, 0, 0}; // unit shading normal, facing the ray origin
  int object = -1;              // create(): 0 = ground plane, 1.. = the objects; create_object(): 0..5 the subject, then the background
};

// The ray-traced scene for a seed, exposed so tests and tools can check a dataset against the
// ground-truth geometry and shading. Thread-safe for concurrent queries once created.
class Scene {
 public:
  static gs::Expected<std::unique_ptr<Scene>> create(uint64_t seed);
  // The object capture's scene (see generate_object): the subject alone, or with its cluttered
  // background; the clutter stands between 1.5 and 2.5 x camera_distance (metres) from the centre.
  static gs::Expected<std::unique_ptr<Scene>> create_object(uint64_t seed, bool cluttered, double camera_distance);
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  int num_objects() const;  // including the ground plane
  // Whether object `object` (a SceneHit::object) belongs to the subject of an object capture; false
  // for every object of create()'s scene and for -1 (the sky).
  bool is_subject(int object) const;
  // Closest hit along origin + t dir, t > 0; false if the ray escapes to the sky.
  bool intersect(const double origin[3], const double dir[3], SceneHit* hit) const;
  // True if anything is hit for t in (0, tfar).
  bool occluded(const double origin[3], const double dir[3], double tfar) const;
  // Shaded colour seen along a ray (sky if nothing is hit), display values in [0, 1].
  void radiance(const double origin[3], const double dir[3], float rgb[3]) const;
  // Renders an 8-bit RGB view with samples_per_axis^2 jittered samples per pixel; the jitter is
  // a function of (jitter_seed, pixel, sample) only, so the result does not depend on `threads`.
  // fisheye_focal > 0: the camera's pose and principal point (cx, cy) through an equidistant fisheye
  // of that focal length (pixels) instead of its pinhole (fx, fy unused): the ray at angle theta
  // from the axis lands at radius fisheye_focal * theta; samples beyond 90 degrees (outside the
  // 180-degree lens's circle) are black.
  gs::io::Image8 render(const gs::Camera& camera, int samples_per_axis, uint64_t jitter_seed, int threads = 0,
                        double fisheye_focal = 0) const;
  // One pass, two layers (either may be null): `composite` is render()'s RGB image; `subject` is
  // RGBA with straight alpha: alpha = the fraction of the samples whose first hit is the subject,
  // RGB = their mean colour (0 where none is).
  void render_layers(const gs::Camera& camera, int samples_per_axis, uint64_t jitter_seed, int threads,
                     gs::io::Image8* composite, gs::io::Image8* subject, double fisheye_focal = 0) const;

 private:
  struct Impl;
  explicit Scene(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace hbgs::synth
