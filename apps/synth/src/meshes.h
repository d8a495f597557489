// SPDX-License-Identifier: MIT
// Triangle meshes for the synthetic scene, built in an object's local frame (z up, metres) with
// per-vertex shading normals; the scene places them with a yaw rotation and a translation.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace hbgs::synth::detail {

struct Mesh {
  std::vector<float> positions;  // [V, 3] metres
  std::vector<float> normals;    // [V, 3] unit shading normals
  std::vector<uint32_t> indices; // [T, 3]
  size_t num_vertices() const { return positions.size() / 3; }
  size_t num_triangles() const { return indices.size() / 3; }
};

// A quad in the z = 0 plane covering [-half, half]^2, normal +z.
Mesh make_ground(double half);
// Sphere of `radius` around the local origin; `slices` around z, `stacks` pole to pole.
Mesh make_uv_sphere(double radius, int slices, int stacks);
// Axis-aligned box centred on the local origin with half extents hx, hy, hz; flat faces.
Mesh make_box(double hx, double hy, double hz);
// Closed cylinder along z from z = 0 to z = height, smooth side and flat caps.
Mesh make_cylinder(double radius, double height, int slices);
// Torus around the z axis: `major` ring radius, `minor` tube radius.
Mesh make_torus(double major, double minor, int major_segments, int minor_segments);

// Rotates about z by `yaw` radians, then translates; positions and normals in place.
void place_mesh(Mesh* mesh, double yaw, const double translation[3]);

}  // namespace hbgs::synth::detail
