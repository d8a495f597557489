// SPDX-License-Identifier: MIT
// The production splatting pipeline: validate -> project (SIMD, parallel over Gaussians) ->
// bin (count -> scan -> emit keys) -> per tile: sort by depth, pack records, blend (SIMD, parallel
// over tiles). Backward: per-tile blend backward into per-intersection gradients, a fixed-order
// reduction to Gaussians, projection backward (parallel, pose gradient summed per chunk in order).
// Pose normal equations: forward-mode twist tangents per Gaussian (parallel), then per tile the
// tangents carried through blending into per-tile J^T W J / J^T W r slots, summed in tile order.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

#include "gs/platform/thread_pool.h"
#include "gs/render.h"
#include "gs/simd/kernel_table.h"
#include "gs/simd/ref.h"
#include "gs/stage_times.h"

namespace gs {
namespace {

constexpr size_t kArenaAlign = 64;
constexpr size_t kExtraBytes = 64;       // over-read pad after every buffer (GS_EXTRA_BYTES)
constexpr size_t kProjectGrain = 1024;   // Gaussians per projection chunk
constexpr size_t kBinRanges = 8;         // most Gaussian ranges binned in parallel
constexpr size_t kMaxReduceBands = 64;   // most Gaussian-id bands the intersection reduce runs in
// Per-tile slot of the pose normal equations (doubles): [0, 21) upper triangle of J^T W J row by
// row, [21, 27) J^T W r, 27 cost, 28 weight sum, 29 pixel count; padded to 32.
constexpr int kPoseSlot = 32;

// Carves typed buffers out of one block; with base == nullptr it only counts (the dry run).
class Carver {
 public:
  explicit Carver(uint8_t* base) : base_(base) {}
  // Sizes are counted in 64 bits so a 32-bit build detects a plan larger than its address space
  // instead of wrapping around.
  template <class T>
  T* take(uint64_t count) {
    offset_ = (offset_ + kArenaAlign - 1) / kArenaAlign * kArenaAlign;
    T* p = base_ ? reinterpret_cast<T*>(base_ + size_t(offset_)) : nullptr;
    offset_ += count * sizeof(T) + kExtraBytes;
    return p;
  }
  uint64_t bytes() const { return offset_ + kArenaAlign; }

 private:
  uint8_t* base_;
  uint64_t offset_ = 0;
};

// Sorts one tile's keys ((depth bits << 32) | id) ascending. Keys arrive in increasing id order
// (emitted Gaussian by Gaussian), so a stable LSD radix sort on the 32 depth bits yields exactly
// the (depth, id) order; passes whose byte is the same for every key are skipped. Small tiles use
// insertion sort. tmp: scratch of n keys.
void sort_tile_keys(uint64_t* keys, uint64_t* tmp, uint32_t n) {
  if (n <= 32) {
    for (uint32_t i = 1; i < n; ++i) {
      const uint64_t k = keys[i];
      uint32_t j = i;
      for (; j > 0 && keys[j - 1] > k; --j) keys[j] = keys[j - 1];
      keys[j] = k;
    }
    return;
  }
  uint64_t* src = keys;
  uint64_t* dst = tmp;
  for (int shift = 32; shift < 64; shift += 8) {
    uint32_t count[256] = {};
    for (uint32_t i = 0; i < n; ++i) ++count[(src[i] >> shift) & 0xFF];
    if (count[(src[0] >> shift) & 0xFF] == n) continue;  // one bucket: this pass would not move anything
    uint32_t offset = 0;
    for (uint32_t& c : count) {
      const uint32_t c0 = c;
      c = offset;
      offset += c0;
    }
    for (uint32_t i = 0; i < n; ++i) dst[count[(src[i] >> shift) & 0xFF]++] = src[i];
    std::swap(src, dst);
  }
  if (src != keys) std::memcpy(keys, src, sizeof(uint64_t) * n);
}

// Index of the lowest set bit of a non-zero word.
inline int lowest_bit(uint64_t bits) {
#if defined(__GNUC__)
  return __builtin_ctzll(bits);
#else
  int k = 0;
  while (!(bits & 1)) bits >>= 1, ++k;
  return k;
#endif
}

// Pixels of a tile (x0, y0, w x h) inside a splat record's alpha >= 1/255 support box (the
// [ext_x, ext_y] half-extents around its mean, pixel centres at +0.5; the kernels' splat_support_box):
// the pixel-splat pairs a tile kernel evaluates, up to lane rounding and early termination. For the
// profile's counting model only.
uint64_t support_pixels_in_tile(const float* s, int x0, int y0, int w, int h) {
  const float ex = s[simd::kSplatExtX], ey = s[simd::kSplatExtY];
  if (!(ex >= 0.0f)) return 0;
  auto span = [](float centre, float ext, int first, int n) -> uint64_t {
    // pixels i in [0, n) with |first + i + 0.5 - centre| <= ext
    const double lo = std::ceil(double(centre) - double(ext) - 0.5 - first);
    const double hi = std::floor(double(centre) + double(ext) - 0.5 - first);
    const double a = std::max(lo, 0.0), b = std::min(hi, double(n - 1));
    return b >= a ? uint64_t(b - a + 1) : 0;
  };
  return span(s[simd::kSplatMx], ex, x0, w) * span(s[simd::kSplatMy], ey, y0, h);
}

template <class F>
void run_parallel(platform::ThreadPool* pool, size_t n, size_t grain, F& f) {
  if (n == 0) return;
  if (pool) {
    pool->parallel_for(n, grain, f);
  } else {
    f(size_t(0), n, 0);
  }
}

}  // namespace

struct Renderer::Impl {
  platform::ThreadPool* pool = nullptr;
  const simd::KernelTable* kernels = nullptr;
  uint8_t* arena = nullptr;
  size_t arena_bytes = 0;
  // per Gaussian
  float *means2d, *conics, *depths, *colors;
  float* records;  // [N, kSplatStride]: each visible Gaussian's splat record, packed once per frame
  int32_t *radii, *rects;
  uint64_t* tile_masks;  // [N] which tiles of a rect of <= 64 tiles the splat reaches (see reached_tiles)
  float *acc_means2d, *acc_conics, *acc_opacities, *acc_colors;
  float *scratch_v_means, *scratch_v_log_scales, *scratch_v_quats;
  double* chunk_pose;  // [chunks, 6]
  float* pose_d_means2d;  // [N, 2, 6] forward-mode twist tangents of mean2d (pose normal equations)
  float* pose_d_conics;   // [N, 3, 6] ... and of the conic
  double* pose_slots;     // [tiles, kPoseSlot] per-tile normal equations
  // per tile
  uint32_t* tile_offsets;  // [tiles + 1]
  uint32_t* range_counts;  // [kBinRanges, tiles] binning: keys per range and tile, then cursors
  size_t range_visible[kBinRanges];
  float range_max_depth[kBinRanges];
  // per intersection
  uint64_t* keys;  // (depth bits << 32) | gaussian id, sorted within each tile
  uint64_t* keys_tmp;  // radix-sort scratch, same layout as keys
  float *splats, *v_splats;
  // per pixel
  float* final_T;
  int32_t* last;
  // last forward
  Camera camera;
  GaussianParams params;
  RenderOptions options;
  simd::ProjectParams pp;
  simd::RasterParams rp;
  simd::QRasterParams qrp;
  size_t num_isects = 0;
  int tiles = 0;
  float campos[3];
  bool forward_ok = false;  // the last forward() completed in float (backward and pose_normal_equations need its state)
  // Profiling (Renderer::set_stage_times): CPU ns of the tile pass's sort + copy and blending, and
  // the support-box pixel count, summed over threads.
  std::atomic<uint64_t> sort_cpu_ns{0}, raster_cpu_ns{0}, splat_pixels{0};

  void carve(Carver& c, const RenderCapacity& cap) {
    const uint64_t G = cap.max_gaussians, I = cap.max_isects, P = uint64_t(cap.max_width) * uint64_t(cap.max_height);
    const uint64_t tiles_max = uint64_t((cap.max_width + simd::kTileSize - 1) / simd::kTileSize) *
                               uint64_t((cap.max_height + simd::kTileSize - 1) / simd::kTileSize);
    means2d = c.take<float>(G * 2);
    conics = c.take<float>(G * 3);
    depths = c.take<float>(G);
    colors = c.take<float>(G * 3);
    records = c.take<float>(G * simd::kSplatStride);
    radii = c.take<int32_t>(G);
    rects = c.take<int32_t>(G * 4);
    tile_masks = c.take<uint64_t>(G);
    acc_means2d = c.take<float>(G * 2);
    acc_conics = c.take<float>(G * 3);
    acc_opacities = c.take<float>(G);
    acc_colors = c.take<float>(G * 3);
    scratch_v_means = c.take<float>(G * 3);
    scratch_v_log_scales = c.take<float>(G * 3);
    scratch_v_quats = c.take<float>(G * 4);
    chunk_pose = c.take<double>((G / kProjectGrain + 1) * 6);
    tile_offsets = c.take<uint32_t>(tiles_max + 1);
    range_counts = c.take<uint32_t>(tiles_max * kBinRanges);
    keys = c.take<uint64_t>(I);
    keys_tmp = c.take<uint64_t>(I);
    splats = c.take<float>(I * simd::kSplatStride);
    v_splats = c.take<float>(I * simd::kSplatStride);
    final_T = c.take<float>(P);
    last = c.take<int32_t>(P);
    pose_d_means2d = c.take<float>(G * 12);
    pose_d_conics = c.take<float>(G * 18);
    pose_slots = c.take<double>(tiles_max * kPoseSlot);
  }

  // One tile of the pose normal equations (see Renderer::pose_normal_equations): re-blends the
  // forward's records front to back up to each pixel's last contributor, carrying the six twist
  // tangents (the scalar twin of simd::raster_pose_jacobian_tile_ref, with the forward's stored
  // last contributor as the early stop), and accumulates w J^T J, w J^T r in double into slot.
  void pose_tile(int tile, const float* target, const float* mask, float huber_delta, float* out_jacobian,
                 double* slot) const {
    double acc[kPoseSlot] = {};
    uint32_t begin, end;
    tile_range(tile, &begin, &end);
    const int x0 = (tile % pp.tiles_x) * simd::kTileSize, y0 = (tile / pp.tiles_x) * simd::kTileSize;
    const int x1 = std::min(x0 + simd::kTileSize, pp.width), y1 = std::min(y0 + simd::kTileSize, pp.height);
    const float* bg = rp.background;
    for (int y = y0; y < y1; ++y) {
      for (int x = x0; x < x1; ++x) {
        const size_t pix = size_t(y) * size_t(pp.width) + size_t(x);
        const bool use = !mask || mask[pix] != 0.0f;
        if (!use && !out_jacobian) continue;
        const float px = float(x) + 0.5f, py = float(y) + 0.5f;
        float trans = 1.0f, rgb[3] = {0, 0, 0};
        float d_trans[6] = {0, 0, 0, 0, 0, 0};
        float d_rgb[18] = {};
        const uint32_t stop = std::min(end, begin + uint32_t(last[pix]));
        for (uint32_t k = begin; k < stop; ++k) {
          const float* s = splats + size_t(k) * simd::kSplatStride;
          // Cheap reject before the exp: power clearly below -two_tau / 2 means alpha < 1/255 (the
          // margin of splat_reaches_tile keeps this from ever overruling eval_splat_ref).
          const float ox = s[simd::kSplatMx] - px, oy = s[simd::kSplatMy] - py;
          const float q = s[simd::kSplatA] * ox * ox + s[simd::kSplatC] * oy * oy + 2.0f * s[simd::kSplatB] * ox * oy;
          if (q > s[simd::kSplatTwoTau] * 1.001f + 2e-3f) continue;
          simd::SplatEval<float> e;
          if (!simd::eval_splat_ref(s, px, py, &e)) continue;
          const size_t g = size_t(uint32_t(keys[k]));
          const float* dm = pose_d_means2d + 12 * g;
          const float* dq = pose_d_conics + 18 * g;
          float d_alpha[6] = {0, 0, 0, 0, 0, 0};
          if (!e.clamped) {
            const float g_mx = -(s[simd::kSplatA] * e.dx + s[simd::kSplatB] * e.dy);
            const float g_my = -(s[simd::kSplatC] * e.dy + s[simd::kSplatB] * e.dx);
            const float g_a = -0.5f * e.dx * e.dx, g_b = -e.dx * e.dy, g_c = -0.5f * e.dy * e.dy;
            for (int q = 0; q < 6; ++q)
              d_alpha[q] = e.alpha * (g_mx * dm[q] + g_my * dm[6 + q] + g_a * dq[q] + g_b * dq[6 + q] + g_c * dq[12 + q]);
          }
          const float w = e.alpha * trans;
          for (int c = 0; c < 3; ++c) {
            const float col = s[simd::kSplatR + c];
            rgb[c] += col * w;
            for (int q = 0; q < 6; ++q) d_rgb[c * 6 + q] += col * (d_alpha[q] * trans + e.alpha * d_trans[q]);
          }
          for (int q = 0; q < 6; ++q) d_trans[q] = d_trans[q] * (1.0f - e.alpha) - trans * d_alpha[q];
          trans *= 1.0f - e.alpha;
        }
        float J[18], r[3];
        for (int c = 0; c < 3; ++c) {
          r[c] = rgb[c] + trans * bg[c] - target[3 * pix + c];
          for (int q = 0; q < 6; ++q) J[c * 6 + q] = d_rgb[c * 6 + q] + bg[c] * d_trans[q];
        }
        if (out_jacobian) std::memcpy(out_jacobian + 18 * pix, J, sizeof(J));
        if (!use) continue;
        const double r2 = double(r[0]) * r[0] + double(r[1]) * r[1] + double(r[2]) * r[2];
        double w = 1.0;
        if (huber_delta > 0.0f) {
          const double rn = std::sqrt(r2);
          if (rn > double(huber_delta)) w = double(huber_delta) / rn;
        }
        int idx = 0;
        for (int i = 0; i < 6; ++i)
          for (int j = i; j < 6; ++j)
            acc[idx++] += w * (double(J[i]) * J[j] + double(J[6 + i]) * J[6 + j] + double(J[12 + i]) * J[12 + j]);
        for (int i = 0; i < 6; ++i)
          acc[21 + i] += w * (double(J[i]) * r[0] + double(J[6 + i]) * r[1] + double(J[12 + i]) * r[2]);
        acc[27] += 0.5 * w * r2;
        acc[28] += w;
        acc[29] += 1.0;
      }
    }
    std::memcpy(slot, acc, sizeof(acc));
  }

  // Bit (ty - rect[1]) * rect width + (tx - rect[0]) set where splat_reaches_tile holds, for a
  // rect of at most 64 tiles (larger rects are tested again by reached_tiles).
  uint64_t reached_tile_mask(size_t i) const {
    return simd::splat_reaches_tiles(means2d + 2 * i, conics + 3 * i, records[i * simd::kSplatStride + simd::kSplatTwoTau],
                                     rects + 4 * i, pp.width, pp.height);
  }
  // Calls f(tile) for every tile Gaussian i is binned to, row by row.
  template <class F>
  void reached_tiles(size_t i, F&& f) const {
    const int32_t* r = rects + 4 * i;
    const int rw = r[2] - r[0];
    if (rw * (r[3] - r[1]) <= 64) {
      const uint64_t row_bits = rw >= 64 ? ~uint64_t(0) : (uint64_t(1) << rw) - 1;
      const uint64_t mask = tile_masks[i];
      for (int ty = r[1], shift = 0; ty < r[3]; ++ty, shift += rw)
        for (uint64_t bits = (mask >> shift) & row_bits; bits != 0; bits &= bits - 1)
          f(ty * pp.tiles_x + r[0] + lowest_bit(bits));
      return;
    }
    const float two_tau = records[i * simd::kSplatStride + simd::kSplatTwoTau];
    for (int ty = r[1]; ty < r[3]; ++ty)
      for (int tx = r[0]; tx < r[2]; ++tx)
        if (simd::splat_reaches_tile(means2d + 2 * i, conics + 3 * i, two_tau, tx, ty, pp.width, pp.height))
          f(ty * pp.tiles_x + tx);
  }

  void tile_range(int tile, uint32_t* begin, uint32_t* end) const {
    *begin = tile_offsets[tile];
    *end = tile_offsets[tile + 1];
  }
};

Renderer::Renderer() : impl_(new Impl()) {}
Renderer::~Renderer() {
  std::free(impl_->arena);
  delete impl_;
}

static RenderCapacity resolved(RenderCapacity cap) {
  if (cap.max_isects == 0) cap.max_isects = size_t(std::min<uint64_t>(16 * uint64_t(cap.max_gaussians), SIZE_MAX));
  return cap;
}

uint64_t Renderer::plan_bytes(const RenderCapacity& capacity) {
  Impl dry;
  Carver c(nullptr);
  dry.carve(c, resolved(capacity));
  return c.bytes();
}

Status Renderer::init(const RenderCapacity& capacity_in, platform::ThreadPool* pool,
                      const simd::KernelTable* kernels) {
  const RenderCapacity capacity = resolved(capacity_in);
  if (capacity.max_width <= 0 || capacity.max_height <= 0 || capacity.max_width > 16384 ||
      capacity.max_height > 16384)
    return invalid_argument("render capacity: image size " + std::to_string(capacity.max_width) + "x" +
                            std::to_string(capacity.max_height) + " is outside 1..16384");
  if (uint64_t(capacity.max_gaussians) >= (uint64_t(1) << 31) || uint64_t(capacity.max_isects) >= (uint64_t(1) << 32))
    return invalid_argument("render capacity: at most 2^31 Gaussians and 2^32 intersections");
  if (capacity.max_sh_degree < 0 || capacity.max_sh_degree > 3)
    return invalid_argument("render capacity: SH degree must be 0..3");
  const uint64_t bytes = plan_bytes(capacity);
  if (bytes > uint64_t(SIZE_MAX) / 2)
    return capacity_exceeded("render arena: the planned " + std::to_string(bytes) +
                             " bytes exceed this platform's address space");
  std::free(impl_->arena);
  impl_->arena = static_cast<uint8_t*>(std::aligned_alloc(kArenaAlign, size_t(bytes + kArenaAlign - 1) / kArenaAlign * kArenaAlign));
  if (!impl_->arena) return capacity_exceeded("render arena: cannot allocate " + std::to_string(bytes) + " bytes");
  impl_->arena_bytes = size_t(bytes);
  Carver c(impl_->arena);
  impl_->carve(c, capacity);
  impl_->pool = pool;
  impl_->kernels = kernels ? kernels : &simd::best_kernel_table();
  capacity_ = capacity;
  return Status::Ok();
}

const char* Renderer::isa() const { return impl_->kernels ? impl_->kernels->isa : "none"; }
const float* Renderer::final_transmittance() const { return impl_->final_T; }
const int32_t* Renderer::last_contributor() const { return impl_->last; }
const int32_t* Renderer::radii() const { return impl_->radii; }

static bool finite(float v) { return std::isfinite(v); }

Status validate_gaussians(const GaussianParams& p) {
  if (p.count > 0 && (!p.means || !p.log_scales || !p.quats || !p.opacities))
    return invalid_argument("Gaussians: means, log_scales, quats and opacities are required");
  if (p.count > 0 && !p.colors && !p.sh) return invalid_argument("Gaussians: either colors or sh is required");
  if (p.sh && (p.sh_degree < 0 || p.sh_degree > 3))
    return invalid_argument("Gaussians: SH degree " + std::to_string(p.sh_degree) + " is outside 0..3");
  const size_t K = size_t((p.sh_degree + 1) * (p.sh_degree + 1));
  auto bad = [](size_t i, const char* field, const std::string& what) {
    return invalid_argument("Gaussian " + std::to_string(i) + ": " + field + " " + what);
  };
  for (size_t i = 0; i < p.count; ++i) {
    for (int k = 0; k < 3; ++k) {
      if (!finite(p.means[3 * i + k])) return bad(i, "mean", "is not finite");
      if (!finite(p.log_scales[3 * i + k])) return bad(i, "log-scale", "is not finite");
    }
    float qn = 0;
    for (int k = 0; k < 4; ++k) {
      if (!finite(p.quats[4 * i + k])) return bad(i, "quaternion", "is not finite");
      qn += p.quats[4 * i + k] * p.quats[4 * i + k];
    }
    if (!(qn > 0)) return bad(i, "quaternion", "is zero");
    const float o = p.opacities[i];
    if (!(o >= 0.0f && o <= 1.0f)) return bad(i, "opacity", "is not in [0, 1]");
    if (p.colors) {
      for (int k = 0; k < 3; ++k)
        if (!finite(p.colors[3 * i + k])) return bad(i, "colour", "is not finite");
    } else {
      for (size_t k = 0; k < K * 3; ++k)
        if (!finite(p.sh[i * K * 3 + k])) return bad(i, "SH coefficient", "is not finite");
    }
  }
  return Status::Ok();
}

Status validate_camera(const Camera& cam) {
  const PinholeIntrinsics& in = cam.intr;
  if (in.width < 1 || in.height < 1) return invalid_argument("camera: image size must be at least 1x1");
  if (!(finite(in.fx) && finite(in.fy) && in.fx > 0 && in.fy > 0))
    return invalid_argument("camera: focal lengths must be positive and finite");
  if (!(finite(in.cx) && finite(in.cy))) return invalid_argument("camera: principal point is not finite");
  for (float v : cam.pose.R)
    if (!finite(v)) return invalid_argument("camera: rotation is not finite");
  for (float v : cam.pose.t)
    if (!finite(v)) return invalid_argument("camera: translation is not finite");
  const float* R = cam.pose.R;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const float d = R[i * 3] * R[j * 3] + R[i * 3 + 1] * R[j * 3 + 1] + R[i * 3 + 2] * R[j * 3 + 2];
      if (std::fabs(d - (i == j ? 1.0f : 0.0f)) > 1e-3f)
        return invalid_argument("camera: rotation is not orthonormal (R R^T differs from I by more than 1e-3)");
    }
  return Status::Ok();
}

Status Renderer::forward(const Camera& camera, const GaussianParams& params, const RenderOptions& options,
                         float* out_rgb, float* out_depth) {
  Impl& m = *impl_;
  if (!m.arena) return invalid_argument("Renderer::forward before init");
  m.forward_ok = false;
  const int W = camera.intr.width, H = camera.intr.height;
  if (options.validate_inputs) {
    GS_RETURN_IF_ERROR(validate_camera(camera));
    GS_RETURN_IF_ERROR(validate_gaussians(params));
  }
  if (W > capacity_.max_width || H > capacity_.max_height)
    return capacity_exceeded("image " + std::to_string(W) + "x" + std::to_string(H) + " exceeds the planned " +
                             std::to_string(capacity_.max_width) + "x" + std::to_string(capacity_.max_height));
  if (params.count > capacity_.max_gaussians)
    return capacity_exceeded(std::to_string(params.count) + " Gaussians exceed the planned " +
                             std::to_string(capacity_.max_gaussians));
  if (params.sh && params.sh_degree > capacity_.max_sh_degree)
    return capacity_exceeded("SH degree exceeds the planned maximum");
  if (!out_rgb || (options.depth && !out_depth)) return invalid_argument("Renderer::forward: missing output buffer");

  m.camera = camera;
  m.params = params;
  m.options = options;
  simd::ProjectParams& pp = m.pp;
  std::memcpy(pp.R, camera.pose.R, sizeof(pp.R));
  std::memcpy(pp.t, camera.pose.t, sizeof(pp.t));
  pp.fx = camera.intr.fx; pp.fy = camera.intr.fy; pp.cx = camera.intr.cx; pp.cy = camera.intr.cy;
  pp.width = W; pp.height = H;
  simd::finish_project_params(&pp);
  m.rp.width = W; m.rp.height = H;
  std::memcpy(m.rp.background, options.background, sizeof(m.rp.background));
  m.tiles = pp.tiles_x * pp.tiles_y;
  const float* R = camera.pose.R;
  const float* t = camera.pose.t;
  for (int k = 0; k < 3; ++k) m.campos[k] = -(R[k] * t[0] + R[3 + k] * t[1] + R[6 + k] * t[2]);
  StageClock clock(times_);

  // 1. Project (and evaluate SH) in parallel chunks.
  const size_t n = params.count;
  const float* colors = params.sh ? m.colors : params.colors;
  auto project = [&](size_t b, size_t e, int) {
    m.kernels->project_fwd(&pp, e - b, params.means + 3 * b, params.log_scales + 3 * b, params.quats + 4 * b,
                           m.means2d + 2 * b, m.conics + 3 * b, m.depths + b, m.radii + b);
    if (params.sh) simd::sh_fwd_ref<float>(e - b, params.sh_degree, params.means + 3 * b,
                                           params.sh + (b * (params.sh_degree + 1) * (params.sh_degree + 1)) * 3,
                                           m.campos, m.colors + 3 * b);
    // Pack each visible Gaussian's record here, in order, so that binning copies one contiguous
    // record per intersection instead of gathering six arrays at random.
    for (size_t i = b; i < e; ++i) {
      if (m.radii[i] == 0) continue;
      float* s = m.records + i * simd::kSplatStride;
      s[simd::kSplatMx] = m.means2d[2 * i];
      s[simd::kSplatMy] = m.means2d[2 * i + 1];
      s[simd::kSplatA] = m.conics[3 * i];
      s[simd::kSplatB] = m.conics[3 * i + 1];
      s[simd::kSplatC] = m.conics[3 * i + 2];
      s[simd::kSplatOpacity] = params.opacities[i];
      s[simd::kSplatR] = colors[3 * i];
      s[simd::kSplatG] = colors[3 * i + 1];
      s[simd::kSplatBlue] = colors[3 * i + 2];
      s[simd::kSplatDepth] = m.depths[i];
      simd::splat_support(m.conics + 3 * i, params.opacities[i], s + simd::kSplatTwoTau);
      simd::tile_rect_supported(&pp, m.means2d + 2 * i, m.radii[i], s + simd::kSplatTwoTau, m.rects + 4 * i);
      m.tile_masks[i] = m.reached_tile_mask(i);
    }
  };
  run_parallel(m.pool, n, kProjectGrain, project);
  clock.lap(kStageProject);

  // 2. Bin: count intersections per tile, scan, emit keys. The Gaussians are split into
  // contiguous ranges, counted and emitted in parallel (the tiles each Gaussian reaches were found
  // in the projection above); a tile's keys are range 0's, then range 1's, ..., so they arrive in
  // increasing id order as sort_tile_keys needs, whatever the number of ranges.
  // A few ranges per thread (claimed dynamically), so a late thread or a dear range does not
  // leave the other threads waiting.
  const size_t threads = m.pool ? size_t(m.pool->num_threads()) : 1;
  const size_t ranges = threads > 1 ? std::min<size_t>(kBinRanges, 4 * threads) : 1;
  const size_t tiles = size_t(m.tiles);
  auto range_begin = [&](size_t r) { return r * n / ranges; };
  auto count = [&](size_t b, size_t e, int) {
    for (size_t r = b; r < e; ++r) {
      uint32_t* c = m.range_counts + r * tiles;
      std::fill(c, c + tiles, 0u);
      size_t visible = 0;
      float max_depth = 0;
      for (size_t i = range_begin(r); i < range_begin(r + 1); ++i) {
        if (m.radii[i] == 0) continue;
        ++visible;
        max_depth = std::max(max_depth, m.depths[i]);
        m.reached_tiles(i, [&](int tile) { ++c[tile]; });
      }
      m.range_visible[r] = visible;
      m.range_max_depth[r] = max_depth;
    }
  };
  run_parallel(m.pool, ranges, 1, count);
  // Scan: tile_offsets[tile] = keys of the tiles before; each range's count becomes its cursor.
  size_t visible = 0;
  for (size_t r = 0; r < ranges; ++r) visible += m.range_visible[r];
  uint64_t total = 0;  // 64-bit: N x tiles can exceed a 32-bit size_t before the capacity check
  for (size_t tile = 0; tile < tiles; ++tile) {
    m.tile_offsets[tile] = uint32_t(total);
    for (size_t r = 0; r < ranges; ++r) {
      uint32_t& c = m.range_counts[r * tiles + tile];
      const uint32_t k = c;
      c = uint32_t(total);  // wraps only when total exceeds the capacity (< 2^32), refused below
      total += k;
    }
  }
  m.tile_offsets[tiles] = uint32_t(total);
  stats_.visible = visible;
  stats_.isects = size_t(std::min<uint64_t>(total, SIZE_MAX));
  if (total > uint64_t(capacity_.max_isects))
    return capacity_exceeded(std::to_string(total) + " Gaussian-tile intersections exceed the planned " +
                             std::to_string(capacity_.max_isects));
  // Fixed point: each visible Gaussian's record becomes its integer record in place, in the emit
  // pass right after its keys (binning is the last reader of the float fields; a QSplat fills a
  // float record's slot). Depth is stored relative to the farthest visible Gaussian.
  float depth_scale = 0;
  if (options.fixed_point) {
    for (size_t r = 0; r < ranges; ++r) depth_scale = std::max(depth_scale, m.range_max_depth[r]);
    if (!(depth_scale > 0)) depth_scale = 1;
    m.qrp.width = W;
    m.qrp.height = H;
    for (int c = 0; c < 3; ++c) m.qrp.background[c] = simd::q15_from_unit(options.background[c]);
    m.qrp.depth_scale = depth_scale;
  }
  auto emit = [&](size_t b, size_t e, int) {
    for (size_t r = b; r < e; ++r) {
      uint32_t* cursor = m.range_counts + r * tiles;
      for (size_t i = range_begin(r); i < range_begin(r + 1); ++i) {
        if (m.radii[i] == 0) continue;
        uint32_t depth_bits;
        std::memcpy(&depth_bits, m.depths + i, 4);  // depth > near plane > 0: float bits are monotonic
        const uint64_t key = (uint64_t(depth_bits) << 32) | uint64_t(i);
        m.reached_tiles(i, [&](int tile) { m.keys[cursor[tile]++] = key; });
        if (options.fixed_point) {
          simd::QSplat q;
          simd::qsplat_from_record(m.records + i * simd::kSplatStride, depth_scale, &q);
          std::memcpy(m.records + i * simd::kSplatStride, &q, sizeof(q));
        }
      }
    }
  };
  run_parallel(m.pool, ranges, 1, emit);
  m.num_isects = size_t(total);
  clock.lap(kStageBin);
  StageTimes* const times = times_;
  const bool count_pixels = times && times->count_splat_pixels;
  if (times) {
    m.sort_cpu_ns.store(0, std::memory_order_relaxed);
    m.raster_cpu_ns.store(0, std::memory_order_relaxed);
    m.splat_pixels.store(0, std::memory_order_relaxed);
  }

  // 3. Per tile: sort by (depth, id), copy the records in that order, blend.
  auto raster = [&](size_t b, size_t e, int) {
    uint64_t sort_ns = 0, raster_ns = 0, t0 = times ? platform::now_ns() : 0;  // two clock reads per tile
    for (size_t tile = b; tile < e; ++tile) {
      uint32_t begin, end;
      m.tile_range(int(tile), &begin, &end);
      sort_tile_keys(m.keys + begin, m.keys_tmp + begin, end - begin);
      for (uint32_t k = begin; k < end; ++k)
        std::memcpy(m.splats + size_t(k) * simd::kSplatStride, m.records + size_t(uint32_t(m.keys[k])) * simd::kSplatStride,
                    sizeof(float) * simd::kSplatStride);
      const int tx = int(tile) % pp.tiles_x, ty = int(tile) / pp.tiles_x;
      const uint64_t t1 = times ? platform::now_ns() : 0;
      if (options.fixed_point) {
        simd::QSplat* q = reinterpret_cast<simd::QSplat*>(m.splats + size_t(begin) * simd::kSplatStride);
        m.kernels->qraster_fwd_tile(&m.qrp, tx, ty, q, int32_t(end - begin), out_rgb, m.final_T, m.last,
                                    options.depth ? out_depth : nullptr);
      } else {
        m.kernels->raster_fwd_tile(&m.rp, tx, ty, m.splats + size_t(begin) * simd::kSplatStride,
                                   int32_t(end - begin), out_rgb, m.final_T, m.last, options.depth ? out_depth : nullptr);
      }
      if (times) {
        const uint64_t t2 = platform::now_ns();
        sort_ns += t1 - t0;
        raster_ns += t2 - t1;
        t0 = t2;
      }
    }
    if (times) {
      m.sort_cpu_ns.fetch_add(sort_ns, std::memory_order_relaxed);
      m.raster_cpu_ns.fetch_add(raster_ns, std::memory_order_relaxed);
    }
  };
  const uint64_t pass0 = times ? platform::now_ns() : 0;
  run_parallel(m.pool, size_t(m.tiles), 1, raster);
  if (times) {
    // The tile pass interleaves sorting and blending on every thread: its wall time is split in
    // the ratio of their summed CPU times.
    const uint64_t pass = platform::now_ns() - pass0;
    const uint64_t sort_cpu = m.sort_cpu_ns.load(), raster_cpu = m.raster_cpu_ns.load();
    const uint64_t sort_share =
        sort_cpu + raster_cpu > 0 ? uint64_t(double(pass) * double(sort_cpu) / double(sort_cpu + raster_cpu)) : 0;
    times->add(kStageSortCopy, sort_share);
    times->add(kStageRasterFwd, pass - sort_share);
    times->projected += visible;
    times->isects += total;
    times->pixels += uint64_t(W) * uint64_t(H);
    if (count_pixels) {
      // Outside the stages: its wall time is the profile's overhead, which StageTimes keeps apart.
      const uint64_t c0 = platform::now_ns();
      auto count_support = [&](size_t b, size_t e, int) {
        uint64_t pixels = 0;
        for (size_t tile = b; tile < e; ++tile) {
          uint32_t begin, end;
          m.tile_range(int(tile), &begin, &end);
          const int x0 = int(tile) % pp.tiles_x * simd::kTileSize, y0 = int(tile) / pp.tiles_x * simd::kTileSize;
          const int w = std::min(simd::kTileSize, W - x0), h = std::min(simd::kTileSize, H - y0);
          for (uint32_t k = begin; k < end; ++k)
            pixels += support_pixels_in_tile(m.splats + size_t(k) * simd::kSplatStride, x0, y0, w, h);
        }
        m.splat_pixels.fetch_add(pixels, std::memory_order_relaxed);
      };
      run_parallel(m.pool, size_t(m.tiles), 16, count_support);
      times->splat_pixels += m.splat_pixels.load();
      times->overhead_ns += platform::now_ns() - c0;
    }
  }
  m.forward_ok = !options.fixed_point;
  return Status::Ok();
}

Status Renderer::backward(const float* v_rgb, GaussianGrads* grads) {
  Impl& m = *impl_;
  if (!m.arena) return invalid_argument("Renderer::backward before init");
  if (!v_rgb || !grads) return invalid_argument("Renderer::backward: null gradient buffer");
  if (!m.forward_ok) return invalid_argument("Renderer::backward: no successful float forward() (a fixed-point forward has no backward)");
  const GaussianParams& params = m.params;
  const size_t n = params.count;
  const simd::ProjectParams& pp = m.pp;
  StageClock clock(times_);

  // Bands for the reduce below: contiguous ranges of Gaussian ids, one per thread.
  const size_t tiles = size_t(m.tiles);
  const size_t total = m.num_isects;
  const size_t bands = std::max<size_t>(1, std::min<size_t>(kMaxReduceBands, m.pool ? size_t(m.pool->num_threads()) : 1));

  // 1. Per tile: blend backward into per-intersection gradients. The accumulators of the reduce
  // are zeroed in the same pass (one item per band of Gaussian ids after the tiles).
  auto zero_acc = [&](size_t g0, size_t g1) {
    std::fill(m.acc_means2d + 2 * g0, m.acc_means2d + 2 * g1, 0.0f);
    std::fill(m.acc_conics + 3 * g0, m.acc_conics + 3 * g1, 0.0f);
    std::fill(m.acc_opacities + g0, m.acc_opacities + g1, 0.0f);
    std::fill(m.acc_colors + 3 * g0, m.acc_colors + 3 * g1, 0.0f);
  };
  auto raster = [&](size_t b, size_t e, int) {
    for (size_t item = b; item < e; ++item) {
      if (item >= tiles) {
        const size_t r = item - tiles;
        zero_acc(r * n / bands, (r + 1) * n / bands);
        continue;
      }
      uint32_t begin, end;
      m.tile_range(int(item), &begin, &end);
      const int tx = int(item) % pp.tiles_x, ty = int(item) / pp.tiles_x;
      m.kernels->raster_bwd_tile(&m.rp, tx, ty, m.splats + size_t(begin) * simd::kSplatStride, int32_t(end - begin),
                                 m.final_T, m.last, v_rgb, m.v_splats + size_t(begin) * simd::kSplatStride);
    }
  };
  run_parallel(m.pool, tiles + bands, 1, raster);
  clock.lap(kStageRasterBwd);

  // 2. Reduce intersections to Gaussians in a fixed order: every Gaussian sums its intersections
  // in key order (tile-major), starting from zero, whatever the number of threads. Each band owns a
  // contiguous range of Gaussian ids and walks all the keys in order, adding those of its own
  // Gaussians: no two threads write to one accumulator, nor (but at the ends of the ranges) to one
  // cache line. (Bands of tiles instead, whose Gaussian ids interleave, made two threads slower
  // than one: 0.52 -> 0.62 ms on a snowmiku_plush iteration, docs/MODEL.md.)
  auto add = [&m](uint32_t g, size_t k) {
    const float* v = m.v_splats + k * simd::kSplatStride;
    m.acc_means2d[2 * g] += v[simd::kSplatMx];
    m.acc_means2d[2 * g + 1] += v[simd::kSplatMy];
    m.acc_conics[3 * g] += v[simd::kSplatA];
    m.acc_conics[3 * g + 1] += v[simd::kSplatB];
    m.acc_conics[3 * g + 2] += v[simd::kSplatC];
    m.acc_opacities[g] += v[simd::kSplatOpacity];
    m.acc_colors[3 * g] += v[simd::kSplatR];
    m.acc_colors[3 * g + 1] += v[simd::kSplatG];
    m.acc_colors[3 * g + 2] += v[simd::kSplatBlue];
  };
  auto reduce = [&](size_t rb, size_t re, int) {
    for (size_t r = rb; r < re; ++r) {
      if (bands == 1) {  // every key is this band's: no picking (one thread, the boards' common case)
        for (size_t k = 0; k < total; ++k) add(uint32_t(m.keys[k]), k);
        continue;
      }
      // The band's keys of each block are picked without a branch (which Gaussian a key holds is
      // random, so a branch per key would mispredict about half the time), then added in order.
      const uint32_t g0 = uint32_t(r * n / bands), width = uint32_t((r + 1) * n / bands) - g0;
      constexpr size_t kBlock = 1024;
      uint32_t picked[kBlock];
      for (size_t k0 = 0; k0 < total; k0 += kBlock) {
        const size_t k1 = std::min(total, k0 + kBlock);
        size_t count = 0;
        for (size_t k = k0; k < k1; ++k) {
          picked[count] = uint32_t(k);
          count += size_t(uint32_t(m.keys[k]) - g0 < width);  // g0 <= g < g0 + width (unsigned wrap below g0)
        }
        for (size_t j = 0; j < count; ++j) add(uint32_t(m.keys[picked[j]]), picked[j]);
      }
    }
  };
  run_parallel(m.pool, bands, 1, reduce);
  clock.lap(kStageReduce);

  // 3. Projection backward in chunks; each chunk sums its own pose gradient, chunks are summed in order.
  float* v_means = grads->v_means ? grads->v_means : m.scratch_v_means;
  float* v_log_scales = grads->v_log_scales ? grads->v_log_scales : m.scratch_v_log_scales;
  float* v_quats = grads->v_quats ? grads->v_quats : m.scratch_v_quats;
  const size_t chunks = (n + kProjectGrain - 1) / kProjectGrain;
  std::fill(m.chunk_pose, m.chunk_pose + 6 * chunks, 0.0);
  auto project = [&](size_t b, size_t e, int) {
    // The per-Gaussian outputs that are plain copies of the sums.
    if (!params.sh && grads->v_colors)
      std::memcpy(grads->v_colors + 3 * b, m.acc_colors + 3 * b, sizeof(float) * 3 * (e - b));
    if (grads->v_opacities) std::memcpy(grads->v_opacities + b, m.acc_opacities + b, sizeof(float) * (e - b));
    if (grads->v_means2d) std::memcpy(grads->v_means2d + 2 * b, m.acc_means2d + 2 * b, sizeof(float) * 2 * (e - b));
    m.kernels->project_bwd(&pp, e - b, params.means + 3 * b, params.log_scales + 3 * b, params.quats + 4 * b,
                           m.radii + b, m.acc_means2d + 2 * b, m.acc_conics + 3 * b, nullptr, v_means + 3 * b,
                           v_log_scales + 3 * b, v_quats + 4 * b, m.chunk_pose + 6 * (b / kProjectGrain));
  };
  run_parallel(m.pool, n, kProjectGrain, project);
  for (int k = 0; k < 6; ++k) grads->v_pose[k] = 0.0;
  for (size_t c = 0; c < chunks; ++c)
    for (int k = 0; k < 6; ++k) grads->v_pose[k] += m.chunk_pose[6 * c + k];

  // 4. Colours: direct, or through SH (view direction depends on the camera centre C = -R^T t;
  //    a left twist moves C by -R^T rho, so dL/drho += -R dL/dC).
  if (params.sh) {
    float v_campos[3] = {0, 0, 0};
    float* v_sh = grads->v_sh;
    if (v_sh) {
      simd::sh_bwd_ref<float>(n, params.sh_degree, params.means, params.sh, m.campos, m.acc_colors, v_sh, v_means,
                              v_campos);
      const float* R = m.camera.pose.R;
      for (int k = 0; k < 3; ++k)
        grads->v_pose[k] -= double(R[k * 3] * v_campos[0] + R[k * 3 + 1] * v_campos[1] + R[k * 3 + 2] * v_campos[2]);
    }
  }  // (v_colors without SH, v_opacities and v_means2d were copied in step 3)
  clock.lap(kStageProjectBwd);
  return Status::Ok();
}

Status Renderer::pose_normal_equations(const float* target, const float* mask, float huber_delta,
                                       PoseNormalEquations* out, float* out_jacobian) {
  Impl& m = *impl_;
  if (!m.arena) return invalid_argument("Renderer::pose_normal_equations before init");
  if (!m.forward_ok) return invalid_argument("Renderer::pose_normal_equations: no successful forward() to linearise");
  if (!target || !out) return invalid_argument("Renderer::pose_normal_equations: null target or output");
  if (std::isnan(huber_delta)) return invalid_argument("Renderer::pose_normal_equations: Huber delta is NaN");
  const GaussianParams& params = m.params;
  const size_t n = params.count;

  // 1. Forward-mode twist tangents of every visible Gaussian's mean2d and conic (zero if culled).
  auto tangents = [&](size_t b, size_t e, int) {
    simd::project_pose_tangents_ref<float>(&m.pp, e - b, params.means + 3 * b, params.log_scales + 3 * b,
                                           params.quats + 4 * b, m.radii + b, m.pose_d_means2d + 12 * b,
                                           m.pose_d_conics + 18 * b);
  };
  run_parallel(m.pool, n, kProjectGrain, tangents);

  // 2. Per tile: tangents through blending, normal equations into the tile's own slot.
  auto tiles = [&](size_t b, size_t e, int) {
    for (size_t tile = b; tile < e; ++tile)
      m.pose_tile(int(tile), target, mask, huber_delta, out_jacobian, m.pose_slots + tile * kPoseSlot);
  };
  run_parallel(m.pool, size_t(m.tiles), 1, tiles);

  // 3. Fixed-order reduction over tiles (independent of the thread count).
  double acc[kPoseSlot] = {};
  for (int tile = 0; tile < m.tiles; ++tile)
    for (int q = 0; q < 30; ++q) acc[q] += m.pose_slots[size_t(tile) * kPoseSlot + q];
  int idx = 0;
  for (int i = 0; i < 6; ++i)
    for (int j = i; j < 6; ++j) {
      out->JtJ[i * 6 + j] = acc[idx];
      out->JtJ[j * 6 + i] = acc[idx];
      ++idx;
    }
  for (int i = 0; i < 6; ++i) out->Jtr[i] = acc[21 + i];
  out->cost = acc[27];
  out->weight_sum = acc[28];
  out->pixels = size_t(acc[29]);
  return Status::Ok();
}

int32_t Renderer::dominant_gaussian(int x, int y) const {
  const Impl& m = *impl_;
  if (x < 0 || y < 0 || x >= m.pp.width || y >= m.pp.height) return -1;
  const int tile = (y / simd::kTileSize) * m.pp.tiles_x + x / simd::kTileSize;
  uint32_t begin, end;
  m.tile_range(tile, &begin, &end);
  const float px = float(x) + 0.5f, py = float(y) + 0.5f;
  float trans = 1.0f, best_w = 0.0f;
  int32_t best = -1;
  const int32_t last = m.last[size_t(y) * m.pp.width + x];
  for (uint32_t k = begin; k < begin + uint32_t(last) && k < end; ++k) {
    const float* s = m.splats + size_t(k) * simd::kSplatStride;
    const float dx = s[simd::kSplatMx] - px, dy = s[simd::kSplatMy] - py;
    const float power = -0.5f * (s[simd::kSplatA] * dx * dx + s[simd::kSplatC] * dy * dy) - s[simd::kSplatB] * dx * dy;
    if (power > 0.0f) continue;
    const float alpha = std::min(simd::kAlphaMax, s[simd::kSplatOpacity] * std::exp(power));
    if (alpha < simd::kAlphaMin) continue;
    const float w = alpha * trans;
    if (w > best_w) {
      best_w = w;
      best = int32_t(uint32_t(m.keys[k]));
    }
    trans *= 1.0f - alpha;
  }
  return best;
}

}  // namespace gs
