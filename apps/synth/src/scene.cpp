// SPDX-License-Identifier: MIT
// The synth scene: procedural meshes in an Embree 3 BVH, procedural albedo per object, and the
// shading model (ambient + Lambert + Blinn-Phong from one sun with hard ray-traced shadows).
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "gs/constants.h"
#include "gs/platform/thread_pool.h"
#include "hbgs/synth.h"
#include "meshes.h"
#include "procedural.h"
#include "view_math.h"

namespace hbgs::synth {
namespace {

using detail::Mesh;

using gs::kPi;

enum class Pattern { kGround, kStripes, kChecker, kBands, kDots, kNoise };

struct Object {
  Pattern pattern = Pattern::kGround;
  double centre[3] = {0, 0, 0};  // local origin in the world, metres
  double yaw = 0;                // rotation about z, radians
  double size = 1;               // pattern scale: radius, half extent or height, metres
  double size2 = 0;              // second size (torus ring radius), metres
  double specular = 0.1;         // Blinn-Phong weight
  double shininess = 32;         // Blinn-Phong exponent
  uint64_t noise_seed = 0;
  Mesh mesh;                     // world space
};

struct Vec3 {
  double x, y, z;
};
inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 normalize(Vec3 a) {
  double n = std::sqrt(dot(a, a));
  return n > 0 ? (1.0 / n) * a : a;
}
inline Vec3 mix(Vec3 a, Vec3 b, double t) { return a + t * (b - a); }
inline double clamp01(double v) { return std::min(1.0, std::max(0.0, v)); }
inline double smoothstep(double e0, double e1, double x) { return detail::smooth(clamp01((x - e0) / (e1 - e0))); }

// Sun direction (towards the light), sun and ambient strengths: display-referred, no units.
const Vec3 kToSun = normalize({0.45, -0.55, 0.78});
constexpr double kSun = 0.85;
constexpr double kAmbient = 0.32;
// Ground half extent, metres: far enough that every camera's lower image half sees ground.
constexpr double kGroundHalf = 30.0;
// Offset of shadow-ray origins along the geometric normal, metres; well above float resolution
// of coordinates within the ground's extent (~4e-6 m at 30 m).
constexpr double kShadowEps = 2e-4;

Vec3 sky(Vec3 d) {
  d = normalize(d);
  const Vec3 zenith{0.30, 0.50, 0.86}, horizon{0.80, 0.86, 0.93}, below{0.58, 0.60, 0.62};
  if (d.z >= 0) return mix(horizon, zenith, d.z * (2.0 - d.z));  // eases out towards the zenith
  return mix(horizon, below, smoothstep(0.0, 0.15, -d.z));
}

// Albedo of object `o` at world point p, from the object's local coordinates so the texture
// moves with the object.
Vec3 albedo(const Object& o, Vec3 p) {
  Vec3 d{p.x - o.centre[0], p.y - o.centre[1], p.z - o.centre[2]};
  double c = std::cos(o.yaw), s = std::sin(o.yaw);
  Vec3 q{c * d.x + s * d.y, -s * d.x + c * d.y, d.z};
  switch (o.pattern) {
    case Pattern::kGround: {
      // 0.5 m checker whose contrast fades with distance (avoids moire at grazing angles),
      // modulated by 1.4 m blotches and fine 0.25 m noise.
      double r = std::hypot(p.x, p.y);
      int parity = int(std::floor(p.x / 0.5) + std::floor(p.y / 0.5)) & 1;
      const Vec3 a{0.80, 0.74, 0.60}, b{0.34, 0.40, 0.28};
      double contrast = 1.0 / (1.0 + (r / 7.0) * (r / 7.0));
      Vec3 base = mix(0.5 * (a + b), parity ? a : b, contrast);
      double blotch = 0.70 + 0.45 * detail::value_noise(o.noise_seed, p.x * 0.7, p.y * 0.7, 0.0);
      double fine = 1.0 + contrast * 0.35 * (detail::fbm(o.noise_seed + 1, p.x * 4.0, p.y * 4.0, 0.5, 2) - 0.5);
      return (blotch * fine) * base;
    }
    case Pattern::kStripes: {
      // Helical stripes: 9 per half-turn in latitude, 2 windings in longitude (integer so the
      // pattern is continuous across the seam).
      Vec3 n = normalize(q);
      double phi = std::asin(std::max(-1.0, std::min(1.0, n.z)));
      double theta = std::atan2(n.y, n.x);
      double t = smoothstep(-0.2, 0.2, std::sin(9.0 * phi + 2.0 * theta));
      Vec3 col = mix(Vec3{0.93, 0.88, 0.74}, Vec3{0.74, 0.14, 0.12}, t);
      return (0.9 + 0.2 * detail::value_noise(o.noise_seed, q.x * 6, q.y * 6, q.z * 6)) * col;
    }
    case Pattern::kChecker: {
      // 3D checker, 0.16 m cells offset by 0.05 m so no face lies on a cell boundary.
      int parity = int(std::floor((q.x + 0.05) / 0.16) + std::floor((q.y + 0.05) / 0.16) +
                       std::floor((q.z + 0.05) / 0.16)) & 1;
      Vec3 col = parity ? Vec3{0.12, 0.22, 0.58} : Vec3{0.95, 0.80, 0.22};
      return (0.85 + 0.3 * detail::value_noise(o.noise_seed, q.x * 5, q.y * 5, q.z * 5)) * col;
    }
    case Pattern::kBands: {
      // Vertical gradient green -> purple, 10 vertical ribs and noisy horizontal bands.
      double h = clamp01(q.z / o.size);
      Vec3 col = mix(Vec3{0.16, 0.62, 0.30}, Vec3{0.58, 0.24, 0.72}, h);
      double theta = std::atan2(q.y, q.x);
      double ribs = 0.72 + 0.28 * smoothstep(-0.3, 0.3, std::sin(10.0 * theta));
      double bands = 0.75 + 0.5 * detail::value_noise(o.noise_seed, 0.0, 0.0, q.z * 7.0);
      return (ribs * bands) * col;
    }
    case Pattern::kDots: {
      // Polka dots on the torus surface: 14 around the ring, 6 around the tube.
      double u = std::atan2(q.y, q.x);
      Vec3 radial{std::cos(u), std::sin(u), 0.0};
      Vec3 w = q - o.size * radial;
      double v = std::atan2(w.z, dot(w, radial));
      double a = u / (2 * kPi) * 14.0, b = v / (2 * kPi) * 6.0;
      double da = a - std::round(a), db = b - std::round(b);
      double dist = std::sqrt(da * da + db * db);
      double t = smoothstep(0.26, 0.32, dist);
      return mix(Vec3{0.96, 0.95, 0.90}, Vec3{0.90, 0.42, 0.08}, t);
    }
    case Pattern::kNoise: {
      // Fractal noise through a teal -> pink -> yellow colour ramp.
      double f = detail::fbm(o.noise_seed, q.x * 5 + 10, q.y * 5 + 10, q.z * 5 + 10, 4);
      f = clamp01((f - 0.5) * 2.4 + 0.5);
      const Vec3 c0{0.10, 0.55, 0.60}, c1{0.90, 0.40, 0.62}, c2{0.96, 0.86, 0.30};
      return f < 0.5 ? mix(c0, c1, f * 2) : mix(c1, c2, f * 2 - 1);
    }
  }
  return {0.5, 0.5, 0.5};
}

void to_array(Vec3 v, double out[3]) {
  out[0] = v.x;
  out[1] = v.y;
  out[2] = v.z;
}

}  // namespace

struct Scene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Object> objects;  // index = Embree geometry id
  std::vector<bool> subject;    // per object: part of the subject (render_layers' coverage)

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  struct RawHit {
    double t;
    unsigned geom, prim;
    float u, v;
    Vec3 ng;  // unnormalised geometric normal
  };

  bool raw_intersect(Vec3 o, Vec3 d, RawHit* out) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    rh.ray.org_x = float(o.x);
    rh.ray.org_y = float(o.y);
    rh.ray.org_z = float(o.z);
    rh.ray.dir_x = float(d.x);
    rh.ray.dir_y = float(d.y);
    rh.ray.dir_z = float(d.z);
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    out->t = rh.ray.tfar;
    out->geom = rh.hit.geomID;
    out->prim = rh.hit.primID;
    out->u = rh.hit.u;
    out->v = rh.hit.v;
    out->ng = {rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z};
    return true;
  }

  bool occluded(Vec3 o, Vec3 d, double tfar) const {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay ray;
    ray.org_x = float(o.x);
    ray.org_y = float(o.y);
    ray.org_z = float(o.z);
    ray.dir_x = float(d.x);
    ray.dir_y = float(d.y);
    ray.dir_z = float(d.z);
    ray.tnear = 0.0f;
    ray.tfar = std::isinf(tfar) ? std::numeric_limits<float>::infinity() : float(tfar);
    ray.time = 0.0f;
    ray.mask = 0xFFFFFFFFu;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(scene, &ctx, &ray);
    // Embree marks an occluded ray by setting tfar to -inf.
    return ray.tfar < 0.0f;
  }

  // The Embree BVH over the objects.
  gs::Status build() {
    device = rtcNewDevice(nullptr);
    if (!device) {
      return gs::Status(gs::StatusCode::kInternal,
                        "synth: rtcNewDevice failed (Embree error " + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
    }
    scene = rtcNewScene(device);
    // Robust traversal so rays through shared triangle edges never slip between two triangles.
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    for (size_t id = 0; id < objects.size(); ++id) {
      const Mesh& m = objects[id].mesh;
      RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      if (!geom) break;
      auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                             3 * sizeof(float), m.num_vertices()));
      auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                3 * sizeof(unsigned), m.num_triangles()));
      if (vb && ib) {
        std::copy(m.positions.begin(), m.positions.end(), vb);
        std::copy(m.indices.begin(), m.indices.end(), ib);
        rtcCommitGeometry(geom);
        rtcAttachGeometryByID(scene, geom, unsigned(id));
      }
      rtcReleaseGeometry(geom);  // the scene holds its own reference
    }
    rtcCommitScene(scene);
    RTCError err = rtcGetDeviceError(device);
    if (err != RTC_ERROR_NONE) {
      return gs::Status(gs::StatusCode::kInternal, "synth: building the Embree scene failed (Embree error " +
                                                       std::to_string(int(err)) + ")");
    }
    return gs::Status::Ok();
  }

  // Full hit record: position on the double-precision ray, facing shading normal.
  bool intersect(Vec3 o, Vec3 d, SceneHit* hit, Vec3* ng_facing) const {
    RawHit raw;
    if (!raw_intersect(o, d, &raw)) return false;
    const Object& obj = objects[raw.geom];
    const uint32_t* tri = &obj.mesh.indices[3 * size_t(raw.prim)];
    const float* n0 = &obj.mesh.normals[3 * size_t(tri[0])];
    const float* n1 = &obj.mesh.normals[3 * size_t(tri[1])];
    const float* n2 = &obj.mesh.normals[3 * size_t(tri[2])];
    double w0 = 1.0 - double(raw.u) - double(raw.v);
    Vec3 ns = normalize({w0 * n0[0] + raw.u * n1[0] + raw.v * n2[0], w0 * n0[1] + raw.u * n1[1] + raw.v * n2[1],
                         w0 * n0[2] + raw.u * n1[2] + raw.v * n2[2]});
    Vec3 ng = normalize(raw.ng);
    if (dot(ng, d) > 0) ng = -1.0 * ng;
    // Interpolated normals can tilt away from the viewer near silhouettes; fall back to the
    // geometric normal there so shading never sees a back-facing normal.
    if (dot(ns, d) >= 0) ns = ng;
    hit->t = raw.t;
    to_array(o + raw.t * d, hit->position);
    to_array(ns, hit->normal);
    hit->object = int(raw.geom);
    if (ng_facing) *ng_facing = ng;
    return true;
  }

  // Colour seen along a ray; *object = the geometry hit first (-1: the sky).
  Vec3 radiance(Vec3 o, Vec3 d, int* object = nullptr) const {
    SceneHit hit;
    Vec3 ng;
    if (object) *object = -1;
    if (!intersect(o, d, &hit, &ng)) return sky(d);
    if (object) *object = hit.object;
    const Object& obj = objects[size_t(hit.object)];
    Vec3 p{hit.position[0], hit.position[1], hit.position[2]};
    Vec3 n{hit.normal[0], hit.normal[1], hit.normal[2]};
    Vec3 a = albedo(obj, p);
    double ndl = dot(n, kToSun);
    double lit = 0;
    if (ndl > 0 && dot(ng, kToSun) > 0) {
      lit = occluded(p + kShadowEps * ng, kToSun, std::numeric_limits<double>::infinity()) ? 0.0 : 1.0;
    }
    // Hemispherical ambient: brighter for upward-facing normals, a cheap sky-light cue.
    double amb = kAmbient * (0.75 + 0.25 * n.z);
    Vec3 col = (amb + kSun * std::max(0.0, ndl) * lit) * a;
    if (lit > 0) {
      Vec3 h = normalize(kToSun - normalize(d));
      double spec = std::pow(std::max(0.0, dot(n, h)), obj.shininess);
      col = col + (kSun * obj.specular * spec) * Vec3{1, 1, 1};
    }
    return col;
  }
};

Scene::Scene(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Scene::~Scene() = default;

namespace {

// Adds objects with a seeded placement jitter (metres) and yaw; `jitter` 0 places them exactly.
struct LayoutBuilder {
  std::vector<Object>* objects;
  std::vector<bool>* subject_flags;
  detail::Rng rng;
  void add(Pattern pattern, Mesh mesh, double x, double y, double z, double size, double size2, double spec, double shin,
           double jitter, bool subject) {
    Object o;
    o.pattern = pattern;
    const double jx = jitter > 0 ? rng.uniform(-jitter, jitter) : 0.0;
    const double jy = jitter > 0 ? rng.uniform(-jitter, jitter) : 0.0;
    o.yaw = jitter > 0 ? rng.uniform(0.0, 2 * kPi) : 0.0;
    o.centre[0] = x + jx;
    o.centre[1] = y + jy;
    o.centre[2] = z;
    o.size = size;
    o.size2 = size2;
    o.specular = spec;
    o.shininess = shin;
    o.noise_seed = rng.next();
    detail::place_mesh(&mesh, o.yaw, o.centre);
    o.mesh = std::move(mesh);
    objects->push_back(std::move(o));
    subject_flags->push_back(subject);
  }
};

}  // namespace

gs::Expected<std::unique_ptr<Scene>> Scene::create(uint64_t seed) {
  auto impl = std::make_unique<Impl>();
  // Layout: ground plus five objects around the origin; the seed jitters their placement and
  // rotation by a few centimetres / any angle and picks the noise fields.
  LayoutBuilder b{&impl->objects, &impl->subject, detail::Rng(detail::hash_combine(seed, 0x5ce7e0b5ULL))};
  b.add(Pattern::kGround, detail::make_ground(kGroundHalf), 0, 0, 0, kGroundHalf, 0, 0.04, 16, 0, false);
  b.add(Pattern::kStripes, detail::make_uv_sphere(0.55, 64, 32), -1.0, -0.3, 0.55, 0.55, 0, 0.35, 48, 0.12, true);
  b.add(Pattern::kChecker, detail::make_box(0.38, 0.38, 0.38), 0.95, -0.55, 0.38, 0.38, 0, 0.15, 24, 0.12, true);
  b.add(Pattern::kBands, detail::make_cylinder(0.32, 1.3, 64), 0.25, 0.85, 0.0, 1.3, 0, 0.25, 32, 0.12, true);
  b.add(Pattern::kDots, detail::make_torus(0.42, 0.14, 72, 24), -1.0, 1.1, 0.14, 0.42, 0.14, 0.30, 40, 0.12, true);
  b.add(Pattern::kNoise, detail::make_uv_sphere(0.32, 48, 24), 1.25, 0.75, 0.32, 0.32, 0, 0.45, 64, 0.12, true);
  GS_RETURN_IF_ERROR(impl->build());
  return std::unique_ptr<Scene>(new Scene(std::move(impl)));
}

gs::Expected<std::unique_ptr<Scene>> Scene::create_object(uint64_t seed, bool cluttered, double camera_distance) {
  auto impl = std::make_unique<Impl>();
  // The subject (object ids 0..5): a checkered pedestal (radius 0.5 m, 0.1 m high, base at z = 0)
  // holding five small shapes, each nudged by up to 1.5 cm and turned by a seeded yaw. It fits in
  // the sphere of radius kObjectRadius around kObjectCentre.
  LayoutBuilder b{&impl->objects, &impl->subject, detail::Rng(detail::hash_combine(seed, 0x0b1ec7ULL))};
  const double top = 0.1;
  b.add(Pattern::kChecker, detail::make_cylinder(0.5, top, 96), 0, 0, 0, top, 0, 0.10, 16, 0, true);
  b.add(Pattern::kStripes, detail::make_uv_sphere(0.17, 64, 32), -0.2, -0.14, top + 0.17, 0.17, 0, 0.35, 48, 0.015, true);
  // Half side 0.12, not 0.11: the checker's cell borders (0.16 m cells offset by 0.05 m) must not lie
  // on a face, where the parity would flip from ray to ray.
  b.add(Pattern::kChecker, detail::make_box(0.12, 0.12, 0.12), 0.22, -0.17, top + 0.12, 0.12, 0, 0.15, 24, 0.015, true);
  b.add(Pattern::kBands, detail::make_cylinder(0.09, 0.42, 64), 0.04, 0.22, top, 0.42, 0, 0.25, 32, 0.015, true);
  b.add(Pattern::kDots, detail::make_torus(0.14, 0.05, 72, 24), -0.24, 0.17, top + 0.05, 0.14, 0.05, 0.30, 40, 0.015, true);
  b.add(Pattern::kNoise, detail::make_uv_sphere(0.1, 48, 24), 0.3, 0.15, top + 0.1, 0.1, 0, 0.45, 64, 0.015, true);
  if (cluttered) {
    // Background: textured ground under the pedestal and clutter 1.5-2.5 camera distances out,
    // beyond every camera, so nothing ever stands between a camera and the subject, and too low
    // (<= 0.5 m) to shadow it under the 51-degree sun.
    b.add(Pattern::kGround, detail::make_ground(kGroundHalf), 0, 0, 0, kGroundHalf, 0, 0.04, 16, 0, false);
    const Pattern patterns[] = {Pattern::kStripes, Pattern::kChecker, Pattern::kBands, Pattern::kDots, Pattern::kNoise};
    for (int i = 0; i < 14; ++i) {
      const double az = 2 * kPi * (i + b.rng.uniform(0.0, 0.6)) / 14;
      const double r = camera_distance * b.rng.uniform(1.5, 2.5);
      const double x = r * std::cos(az), y = r * std::sin(az), size = b.rng.uniform(0.15, 0.25);
      const Pattern p = patterns[i % 5];
      switch (i % 4) {
        case 0: b.add(p, detail::make_uv_sphere(size, 32, 16), x, y, size, size, 0, 0.3, 32, 0, false); break;
        case 1: b.add(p, detail::make_box(size, size * 0.8, size), x, y, size, size, 0, 0.15, 24, 0, false); break;
        case 2: b.add(p, detail::make_cylinder(size * 0.6, 2 * size, 32), x, y, 0, 2 * size, 0, 0.2, 32, 0, false); break;
        default: b.add(p, detail::make_torus(size, size * 0.35, 48, 16), x, y, size * 0.35, size, size * 0.35, 0.3, 40, 0, false);
      }
    }
  }
  GS_RETURN_IF_ERROR(impl->build());
  return std::unique_ptr<Scene>(new Scene(std::move(impl)));
}

int Scene::num_objects() const { return int(impl_->objects.size()); }

bool Scene::is_subject(int object) const {
  return object >= 0 && object < int(impl_->subject.size()) && impl_->subject[size_t(object)];
}

bool Scene::intersect(const double origin[3], const double dir[3], SceneHit* hit) const {
  SceneHit local;
  bool found = impl_->intersect({origin[0], origin[1], origin[2]}, {dir[0], dir[1], dir[2]}, &local, nullptr);
  if (found && hit) *hit = local;
  return found;
}

bool Scene::occluded(const double origin[3], const double dir[3], double tfar) const {
  return impl_->occluded({origin[0], origin[1], origin[2]}, {dir[0], dir[1], dir[2]}, tfar);
}

void Scene::radiance(const double origin[3], const double dir[3], float rgb[3]) const {
  Vec3 c = impl_->radiance({origin[0], origin[1], origin[2]}, {dir[0], dir[1], dir[2]});
  rgb[0] = float(clamp01(c.x));
  rgb[1] = float(clamp01(c.y));
  rgb[2] = float(clamp01(c.z));
}

gs::io::Image8 Scene::render(const gs::Camera& camera, int samples_per_axis, uint64_t jitter_seed, int threads,
                             double fisheye_focal) const {
  gs::io::Image8 img;
  render_layers(camera, samples_per_axis, jitter_seed, threads, &img, nullptr, fisheye_focal);
  return img;
}

void Scene::render_layers(const gs::Camera& camera, int samples_per_axis, uint64_t jitter_seed, int threads,
                          gs::io::Image8* composite, gs::io::Image8* subject, double fisheye_focal) const {
  const int w = camera.intr.width, h = camera.intr.height;
  const int n = std::max(1, samples_per_axis);
  const auto make = [&](gs::io::Image8* img, int channels) {
    if (!img) return;
    img->width = w;
    img->height = h;
    img->channels = channels;
    img->pixels.assign(size_t(std::max(w, 0)) * size_t(std::max(h, 0)) * size_t(channels), 0);
  };
  make(composite, 3);
  make(subject, 4);
  if (w <= 0 || h <= 0) return;
  const detail::ViewRays rays = fisheye_focal > 0 ? detail::ViewRays(camera, fisheye_focal, 0.5 * 3.14159265358979323846)
                                                   : detail::ViewRays(camera);
  gs::platform::ThreadPool pool(threads);
  pool.for_each_index(size_t(h), [&](size_t row) {
    const int y = int(row);
    for (int x = 0; x < w; ++x) {
      double sum[3] = {0, 0, 0}, own[3] = {0, 0, 0};  // all samples; subject samples only
      int hits = 0;
      for (int s = 0; s < n * n; ++s) {  // n <= 16, so s < 256
        // Stratified jitter: sample s sits in sub-cell (s % n, s / n) at a hashed offset; with one
        // sample per pixel it is the pixel centre.
        double ox = 0.5, oy = 0.5;
        if (n > 1) {
          uint64_t hs = detail::hash_combine(jitter_seed, (uint64_t(y) * uint64_t(w) + uint64_t(x)) * 256 + uint64_t(s));
          ox = (double(s % n) + detail::to_unit(hs)) / n;
          oy = (double(s / n) + detail::to_unit(detail::mix64(hs))) / n;
        }
        double o[3], d[3];
        if (!rays.ray(x + ox, y + oy, o, d)) continue;  // outside the fisheye's circle: black
        int object = -1;
        const Vec3 c = impl_->radiance({o[0], o[1], o[2]}, {d[0], d[1], d[2]}, &object);
        const double rgb[3] = {clamp01(c.x), clamp01(c.y), clamp01(c.z)};
        const bool on_subject = is_subject(object);
        hits += on_subject ? 1 : 0;
        for (int ch = 0; ch < 3; ++ch) {
          sum[ch] += rgb[ch];
          if (on_subject) own[ch] += rgb[ch];
        }
      }
      const size_t i = size_t(y) * size_t(w) + size_t(x);
      if (composite)
        for (int ch = 0; ch < 3; ++ch) composite->pixels[i * 3 + size_t(ch)] = uint8_t(std::lround(sum[ch] / (n * n) * 255.0));
      if (subject) {
        // Straight (not premultiplied) alpha, as PNG stores it: the subject's mean colour, and the
        // fraction of the samples that hit it.
        for (int ch = 0; ch < 3; ++ch)
          subject->pixels[i * 4 + size_t(ch)] = hits ? uint8_t(std::lround(own[ch] / hits * 255.0)) : 0;
        subject->pixels[i * 4 + 3] = uint8_t(std::lround(double(hits) / (n * n) * 255.0));
      }
    }
  });
}

}  // namespace hbgs::synth
