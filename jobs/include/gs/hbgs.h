// SPDX-License-Identifier: MIT
// hbgs: hybrid bundle-adjusting 3D Gaussians on the CPU. The umbrella header of the installed
// library (find_package(hbgs) -> hbgs::hbgs, or pkg-config hbgs); docs/API.md says the same at length.
//
// Layers, each using only those below it: gs/status.h, span.h, stats.h, random.h (hbgs::base);
// gs/simd/ kernels (hbgs::simd); gs/platform/ threads, clock, files (hbgs::platform); gs/camera.h, scene_frame.h,
// render.h, gs/pose/pose.h (hbgs::core); gs/io/ COLMAP, NeRF-style transforms.json, images,
// composites, PLY and the splat exchange formats (hbgs::io); gs/metrics/ PSNR, SSIM, LPIPS
// (hbgs::metrics); gs/model/ the hybrid anchor model, trainer, backgrounds and baking to plain
// Gaussians, gs/model/register.h and point_alignment.h (hbgs::model); gs/capture/ cameras, video,
// COLMAP driver (hbgs::capture); gs/jobs/ whole jobs, export included (hbgs::jobs).
//
// Lifecycle: create (validate everything, plan and allocate) -> run (allocation-free calls) ->
// destroy. Renderer::plan/init, ModelRenderer::init, Registrar::create and Trainer::create size
// their memory for the scene they are given; render, register_view and step allocate nothing.
// Jobs (gs::jobs::train_run, evaluate_run) are one call each with one options struct holding every
// default, and report progress through a callback.
// Threads: every object takes an optional platform::ThreadPool*; an object is used by one thread at
// a time; different objects may run concurrently.
// Errors: no exceptions cross the API; calls return gs::Status or gs::Expected<T> whose message
// names the file, record and problem. Kernels are chosen once per process (simd::best_kernel_table).
#pragma once

#include "gs/camera.h"
#include "gs/scene_frame.h"
#include "gs/io/colmap.h"
#include "gs/io/composite.h"
#include "gs/io/image.h"
#include "gs/io/ply.h"
#include "gs/io/splat_formats.h"
#include "gs/io/transforms.h"
#include "gs/jobs/compact.h"
#include "gs/jobs/evaluate.h"
#include "gs/jobs/export.h"
#include "gs/jobs/pose_truth.h"
#include "gs/jobs/register.h"
#include "gs/jobs/render.h"
#include "gs/jobs/report.h"
#include "gs/jobs/run_folder.h"
#include "gs/jobs/train.h"
#include "gs/model/background.h"
#include "gs/model/bake.h"
#include "gs/model/compact_model.h"
#include "gs/model/evaluate.h"
#include "gs/model/hybrid_model.h"
#include "gs/model/model_renderer.h"
#include "gs/model/trainer.h"
#include "gs/model/register.h"
#include "gs/platform/thread_pool.h"
#include "gs/pose/pose.h"
#include "gs/render.h"
#include "gs/simd/kernel_table.h"
#include "gs/status.h"
