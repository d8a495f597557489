// SPDX-License-Identifier: MIT
// A registrar that borrows a trainer's renderer, decode backend and step workspace instead of
// planning its own (private to gs_model). Registering held-back views between training steps with
// its own set cost snowmiku_plush about 36 MiB of resident memory (a full-resolution render and the
// decode buffers of every anchor row, again); the trainer's set is idle between steps and already
// planned for the same model and image size.
#pragma once

#include <memory>

#include "float_backend.h"
#include "gs/model/register.h"
#include "gs/model/step_graph.h"

namespace gs::pose {

struct RegistrarSharing {
  // As Registrar::create for an anchor model, with the renderer (planned for images of at least
  // max_width x max_height), backend and workspace (for at least the planned anchor rows) of the
  // caller. They must outlive the registrar, and the caller must not use them while a
  // registration or render runs; between calls they hold nothing the registrar needs (the last
  // decode is redone at the next call). The renderer is re-planned when a view needs more tile
  // pairs than it holds; the workspace grows as the caller's own decodes grow it.
  static Expected<std::unique_ptr<Registrar>> create(const model::HybridModel& model, int max_width, int max_height,
                                                     const RegisterOptions& options, platform::ThreadPool* pool,
                                                     const simd::KernelTable* kernels, size_t plan_anchor_rows,
                                                     Renderer* renderer, model::detail::FloatBackend* backend,
                                                     model::StepWorkspace<float>* ws);
};

}  // namespace gs::pose
