// SPDX-License-Identifier: MIT
// KernelTable: one set of function pointers per instruction set, filled once at start-up; nothing
// dispatches per call. The "ref" table points at the scalar reference kernels (the spec); the SIMD
// tables hold xsimd variants compiled in per-ISA translation units (sse2 / avx2 / avx512 on x86,
// neon64 on aarch64, neon on armv7). Callers pick best_kernel_table() unless they compare variants.
#pragma once

#include <cstddef>
#include <cstdint>

#include "gs/simd/convert.h"
#include "gs/simd/loss.h"
#include "gs/simd/mlp.h"
#include "gs/simd/qmlp.h"
#include "gs/simd/qsplat.h"
#include "gs/simd/splat.h"

namespace gs::simd {

using ProjectFwdFn = void (*)(const ProjectParams*, size_t n, const float* means, const float* log_scales,
                              const float* quats, float* means2d, float* conics, float* depths, int32_t* radii);
using ProjectBwdFn = void (*)(const ProjectParams*, size_t n, const float* means, const float* log_scales,
                              const float* quats, const int32_t* radii, const float* v_means2d, const float* v_conics,
                              const float* v_depths, float* v_means, float* v_log_scales, float* v_quats,
                              double* v_pose);
using RasterFwdTileFn = void (*)(const RasterParams*, int32_t tile_x, int32_t tile_y, const float* splats,
                                 int32_t count, float* out_rgb, float* out_T, int32_t* out_last, float* out_depth);
using RasterBwdTileFn = void (*)(const RasterParams*, int32_t tile_x, int32_t tile_y, const float* splats,
                                 int32_t count, const float* final_T, const int32_t* last, const float* v_rgb,
                                 float* v_splats);
using LossFwdFn = void (*)(const LossParams*, int32_t width, int32_t height, const float* image, const float* target,
                           float* scratch, double* out_l1, double* out_ssim);
using LossBwdFn = void (*)(const LossParams*, int32_t width, int32_t height, const float* image, const float* target,
                           double v_loss, float* scratch, float* v_image, double* out_l1, double* out_ssim);
using LossBwdRowsFn = void (*)(const LossParams*, int32_t width, int32_t height, int32_t row_begin, int32_t row_end,
                               const float* image, const float* target, double v_loss, float* scratch,
                               float* v_image, double* row_l1, double* row_ssim);
using MlpFwdFn = void (*)(const MlpShape*, int32_t batch, const float* x, const float* W1, const float* b1,
                          const float* W2, const float* b2, float* hidden, float* y);
using MlpBwdFn = void (*)(const MlpShape*, int32_t batch, const float* x, const float* W1, const float* b1,
                          const float* W2, const float* b2, const float* hidden, const float* y, const float* v_y,
                          float* v_x, float* v_W1, float* v_b1, float* v_W2, float* v_b2);
using AdamStepFn = void (*)(const AdamParams*, size_t n, float* param, const float* grad, float* m, float* v);
using YuyvToRgbFn = void (*)(int32_t width, int32_t height, const uint8_t* yuyv, int32_t yuyv_stride, uint8_t* rgb,
                             int32_t rgb_stride);
using Nv12ToRgbFn = void (*)(int32_t width, int32_t height, const uint8_t* y, int32_t y_stride, const uint8_t* uv,
                             int32_t uv_stride, uint8_t* rgb, int32_t rgb_stride);
using QRasterFwdTileFn = void (*)(const QRasterParams*, int32_t tile_x, int32_t tile_y, const QSplat* splats,
                                  int32_t count, float* out_rgb, float* out_T, int32_t* out_last, float* out_depth);
using QMlpFwdFn = void (*)(const QMlpParams*, int32_t batch, const int16_t* x, int16_t* hidden, int16_t* y);

struct KernelTable {
  const char* isa;  // "ref", "sse2", "avx2", "avx512", "neon64", "neon"
  int lanes;        // float lanes of the variant (1 for ref)
  ProjectFwdFn project_fwd;
  ProjectBwdFn project_bwd;
  RasterFwdTileFn raster_fwd_tile;
  RasterBwdTileFn raster_bwd_tile;
  LossFwdFn loss_fwd;  // photometric loss over a whole [H, W, 3] image (loss.h)
  LossBwdFn loss_bwd;
  MlpFwdFn mlp_fwd;  // 2-layer decoder MLP over a batch of rows (mlp.h)
  MlpBwdFn mlp_bwd;
  AdamStepFn adam_step;  // one Adam update of n parameters (mlp.h)
  YuyvToRgbFn yuyv_to_rgb;  // camera frames to RGB24, bit-identical across tables (convert.h)
  Nv12ToRgbFn nv12_to_rgb;
  QRasterFwdTileFn qraster_fwd_tile;  // fixed-point forward of one tile, bit-identical across tables (qsplat.h)
  QMlpFwdFn qmlp_fwd;                 // int8 decoder MLP over a batch of rows, bit-identical across tables (qmlp.h)
  LossBwdRowsFn loss_bwd_rows;        // loss_bwd for a band of rows, with per-row sums (parallel bands; loss.h)
  // mlp_fwd bit-identical to mlp_fwd_ref on every table (lanes along the rows, double accumulation
  // in the reference's order; kernels/mlp/mlp_exact.hpp): the on-device decode, whose poses must not
  // depend on the CPU. Slower than mlp_fwd.
  MlpFwdFn mlp_fwd_exact;
};

// The reference table (always available).
const KernelTable& ref_kernel_table();
// Every SIMD table compiled into this build and supported by this CPU, best first.
// Returns the number written to out (at most max_tables).
int available_simd_kernel_tables(const KernelTable** out, int max_tables);
// Best SIMD table for this CPU, or the ref table if none is available.
const KernelTable& best_kernel_table();
// Table by ISA name ("ref", "sse2", ...), or nullptr if not compiled in or not supported here.
const KernelTable* kernel_table_by_name(const char* isa);

}  // namespace gs::simd
