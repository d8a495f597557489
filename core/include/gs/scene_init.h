// SPDX-License-Identifier: MIT
// Building a renderable Gaussian set: initialisation from SfM points (3DGS-style: isotropic scale
// from the 3 nearest neighbours, colour from the point, fixed opacity) and the activation of a
// GaussianCloud (logit opacities) into the renderer's GaussianParams view.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "gs/gaussians.h"
#include "gs/render.h"

namespace gs {

// Mean distance from each point to its k nearest other points ([n], world units), found with a
// uniform grid (exact). Points with no neighbour get the scene's median spacing (or 1 if n == 1).
std::vector<float> mean_knn_distance(const float* xyz, size_t n, int k = 3);

// SH-degree-0 Gaussians at the points: log-scale = log(mean 3-NN distance), identity rotation,
// DC colour from rgb (so the rendered colour equals the point colour), opacity as given.
GaussianCloud gaussians_from_points(const float* xyz, const uint8_t* rgb, size_t n, float opacity = 0.8f);

// A GaussianParams view over a cloud; opacities are activated (sigmoid) into *opacity_storage,
// which must outlive the view.
GaussianParams activate(const GaussianCloud& cloud, std::vector<float>* opacity_storage);

}  // namespace gs
