// SPDX-License-Identifier: MIT
// gs::Renderer: the differentiable CPU tile splatting renderer (forward + backward).
//
// Lifecycle: plan -> init (one allocation: the arena) -> forward/backward any number of times.
// Memory: every buffer lives in the arena sized by plan() from a RenderCapacity (max Gaussians,
// max tile intersections, max image size); forward and backward allocate nothing. Exceeding a
// capacity returns kCapacityExceeded (nothing is reallocated behind the caller's back).
// Threading: work is split over Gaussians (projection) and tiles (rasterisation) on the given
// ThreadPool; results do not depend on the number of threads (reductions run in fixed order).
// Inputs are validated at the API boundary (NaN/Inf, sizes, camera); kernels below trust them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "gs/camera.h"
#include "gs/status.h"

namespace gs::simd { struct KernelTable; }
namespace gs::platform { class ThreadPool; }

namespace gs {

struct StageTimes;  // gs/stage_times.h

// Non-owning view of the Gaussians to render. Exactly one of colors / sh is used.
struct GaussianParams {
  size_t count = 0;
  const float* means = nullptr;       // [N, 3] world
  const float* log_scales = nullptr;  // [N, 3]
  const float* quats = nullptr;       // [N, 4] (w, x, y, z), any non-zero norm
  const float* opacities = nullptr;   // [N] activated, in [0, 1]
  const float* colors = nullptr;      // [N, 3] RGB, or nullptr when sh is given
  const float* sh = nullptr;          // [N, K, 3], K = (sh_degree + 1)^2, evaluated for the view
  int sh_degree = 0;
};

// Gaussians with activated opacities and RGB colours owned in vectors (benchmark and test scenes,
// a cloud decoded for one view), and the renderer's view of them: the one GaussianParams set-up
// from vectors. params() stays valid until a vector is resized.
struct ColoredGaussians {
  std::vector<float> means;       // [N, 3] world
  std::vector<float> log_scales;  // [N, 3]
  std::vector<float> quats;       // [N, 4] (w, x, y, z), any non-zero norm
  std::vector<float> opacities;   // [N] in [0, 1]
  std::vector<float> colors;      // [N, 3] RGB

  size_t size() const { return opacities.size(); }
  void resize(size_t n) {
    means.resize(3 * n);
    log_scales.resize(3 * n);
    quats.resize(4 * n);
    opacities.resize(n);
    colors.resize(3 * n);
  }
  // The first `count` Gaussians (the vectors may hold more: capacity kept across views).
  GaussianParams params(size_t count) const {
    GaussianParams p;
    p.count = count;
    p.means = means.data();
    p.log_scales = log_scales.data();
    p.quats = quats.data();
    p.opacities = opacities.data();
    p.colors = colors.data();
    return p;
  }
  GaussianParams params() const { return params(size()); }
};

// Gradient outputs; any pointer may be null to skip it. Arrays are overwritten.
struct GaussianGrads {
  float* v_means = nullptr;       // [N, 3]
  float* v_log_scales = nullptr;  // [N, 3]
  float* v_quats = nullptr;       // [N, 4] w.r.t. the raw (unnormalised) quaternion
  float* v_opacities = nullptr;   // [N]
  float* v_colors = nullptr;      // [N, 3] (colour input) ...
  float* v_sh = nullptr;          // [N, K, 3] (... or SH input)
  float* v_means2d = nullptr;     // [N, 2] px, the densification statistic
  double v_pose[6] = {0, 0, 0, 0, 0, 0};  // (rho, phi): left twist of the world-to-camera pose
};

// The gradient outputs for Gaussians with colour input (ColoredGaussians, decoded neural Gaussians).
inline GaussianGrads colored_gaussian_grads(float* v_means, float* v_log_scales, float* v_quats, float* v_opacities,
                                            float* v_colors, float* v_means2d) {
  GaussianGrads g;
  g.v_means = v_means;
  g.v_log_scales = v_log_scales;
  g.v_quats = v_quats;
  g.v_opacities = v_opacities;
  g.v_colors = v_colors;
  g.v_means2d = v_means2d;
  return g;
}

struct RenderCapacity {
  size_t max_gaussians = 0;
  size_t max_isects = 0;  // Gaussian-tile pairs; 0: 16 x max_gaussians
  int max_width = 0, max_height = 0;
  int max_sh_degree = 3;
};

struct RenderOptions {
  float background[3] = {0, 0, 0};
  bool depth = false;           // also produce the alpha-weighted depth image
  bool validate_inputs = true;  // scan parameters for NaN/Inf (O(N)); a trusted caller may skip it
  // Blend with the fixed-point tile kernel (gs/simd/qsplat.h: int16, bit-exact across ISAs for the
  // same integer records; colours clamped to [0, 1]). Forward only: backward() and pose_normal_equations() need a float
  // forward and refuse to follow this one.
  bool fixed_point = false;
};

// Per-frame statistics of the last forward.
struct RenderStats {
  size_t visible = 0;  // Gaussians with a non-zero radius
  size_t isects = 0;   // Gaussian-tile pairs
};

// Gauss-Newton normal equations of the photometric residual with respect to the camera pose, for
// the last forward: J = d rgb / d xi per pixel and channel (xi = (rho, phi), the LEFT twist of
// GaussianGrads::v_pose), r = rendered - target, w a per-pixel robust weight.
struct PoseNormalEquations {
  double JtJ[36];       // sum w J^T J, row-major 6x6, symmetric
  double Jtr[6];        // sum w J^T r
  double cost;          // 0.5 sum w |r|^2 (the IRLS-weighted cost at this linearisation point)
  double weight_sum;    // sum of w over the pixels used
  size_t pixels;        // pixels used (mask != 0)
};

class Renderer {
 public:
  Renderer();
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Bytes the arena needs for a capacity (the dry run), counted in 64 bits on every platform.
  static uint64_t plan_bytes(const RenderCapacity& capacity);

  // Allocates the arena. pool may be null (single-threaded); kernels null = best for this CPU.
  Status init(const RenderCapacity& capacity, platform::ThreadPool* pool, const simd::KernelTable* kernels = nullptr);
  const RenderCapacity& capacity() const { return capacity_; }
  const char* isa() const;

  // Renders into out_rgb [H, W, 3] (and out_depth [H, W] if options.depth). Keeps what the
  // backward needs; the parameter arrays must stay unchanged until backward() returns.
  Status forward(const Camera& camera, const GaussianParams& params, const RenderOptions& options, float* out_rgb,
                 float* out_depth = nullptr);
  // Gradients of the last forward given v_rgb = dL/d(out_rgb) [H, W, 3].
  Status backward(const float* v_rgb, GaussianGrads* grads);

  // Normal equations of the pose for the last forward (valid after a successful forward(), whose
  // parameter arrays must still be unchanged, like backward()), by forward-mode differentiation: six twist tangents carried through projection and blending
  // with the forward's skip / clamp / early-stop decisions. Colours and opacities are treated as
  // pose-independent (SH colours stay those evaluated for the forward's view). Per pixel,
  // r = rendered - target (3 channels; the rendered colour is recomputed from the forward's
  // splats), w = 1 if |r|_2 <= huber_delta or huber_delta <= 0, else huber_delta / |r|_2; pixels
  // with mask == 0 are skipped (mask [H, W] or nullptr = all). out_jacobian [H, W, 3, 6], if not
  // null, receives J for every pixel (masked or not). Parallel over tiles with a fixed-order
  // reduction: results do not depend on the thread count. Allocates nothing.
  Status pose_normal_equations(const float* target /*[H, W, 3]*/, const float* mask, float huber_delta,
                               PoseNormalEquations* out, float* out_jacobian = nullptr);

  const RenderStats& stats() const { return stats_; }
  // Profiling: forward() and backward() add their stages' wall time (projection, binning, sort +
  // copy, raster forward / backward, reduce, projection backward) and counts to *times; null (the
  // default) turns it off at the cost of one branch per stage.
  void set_stage_times(StageTimes* times) { times_ = times; }
  // Per-pixel state of the last forward: final transmittance and 1 + index of the last contributor
  // within the pixel's tile list; per-Gaussian radius in px (0 = culled).
  const float* final_transmittance() const;
  const int32_t* last_contributor() const;
  const int32_t* radii() const;
  // Index of the Gaussian that contributes the largest blending weight alpha*T to a pixel, or -1;
  // recomputed on demand (for picking and tests, not for the hot loop).
  int32_t dominant_gaussian(int x, int y) const;

 private:
  struct Impl;
  Impl* impl_;
  RenderCapacity capacity_;
  RenderStats stats_;
  StageTimes* times_ = nullptr;
};

// Validates a Gaussian set: sizes, and every parameter finite; opacities in [0, 1]; quaternions
// non-zero. The message names the first offending Gaussian and field.
Status validate_gaussians(const GaussianParams& params);
// Validates a camera: positive finite focal lengths, finite principal point, size >= 1, rotation
// orthonormal within 1e-3, finite translation.
Status validate_camera(const Camera& camera);

}  // namespace gs
