// SPDX-License-Identifier: MIT
// Procedural triangle meshes (ground quad, UV sphere, box, cylinder, torus) for the synth scene.
#include "meshes.h"

#include <cmath>
#include <utility>

#include "gs/constants.h"

namespace hbgs::synth::detail {
namespace {

using gs::kPi;

uint32_t add_vertex(Mesh* m, double px, double py, double pz, double nx, double ny, double nz) {
  uint32_t id = uint32_t(m->num_vertices());
  m->positions.insert(m->positions.end(), {float(px), float(py), float(pz)});
  m->normals.insert(m->normals.end(), {float(nx), float(ny), float(nz)});
  return id;
}

void add_tri(Mesh* m, uint32_t a, uint32_t b, uint32_t c) { m->indices.insert(m->indices.end(), {a, b, c}); }

}  // namespace

Mesh make_ground(double half) {
  Mesh m;
  uint32_t a = add_vertex(&m, -half, -half, 0, 0, 0, 1);
  uint32_t b = add_vertex(&m, half, -half, 0, 0, 0, 1);
  uint32_t c = add_vertex(&m, half, half, 0, 0, 0, 1);
  uint32_t d = add_vertex(&m, -half, half, 0, 0, 0, 1);
  add_tri(&m, a, b, c);
  add_tri(&m, a, c, d);
  return m;
}

Mesh make_uv_sphere(double radius, int slices, int stacks) {
  Mesh m;
  // (stacks + 1) rings of (slices + 1) vertices; the seam and pole vertices are duplicated so every
  // quad is indexed the same way (degenerate pole triangles are skipped).
  for (int i = 0; i <= stacks; ++i) {
    double phi = kPi * double(i) / stacks;  // 0 at the north pole
    double sp = std::sin(phi), cp = std::cos(phi);
    for (int j = 0; j <= slices; ++j) {
      double th = 2 * kPi * double(j) / slices;
      double nx = sp * std::cos(th), ny = sp * std::sin(th), nz = cp;
      add_vertex(&m, radius * nx, radius * ny, radius * nz, nx, ny, nz);
    }
  }
  auto at = [&](int i, int j) { return uint32_t(i * (slices + 1) + j); };
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      // Counter-clockwise seen from outside.
      if (i != 0) add_tri(&m, at(i, j), at(i + 1, j), at(i, j + 1));
      if (i != stacks - 1) add_tri(&m, at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
    }
  }
  return m;
}

Mesh make_box(double hx, double hy, double hz) {
  Mesh m;
  const double h[3] = {hx, hy, hz};
  // Each face: normal axis a with sign s; the two tangent axes b, c are chosen so (b, c, a) is
  // right-handed and the face winds counter-clockwise from outside.
  for (int a = 0; a < 3; ++a) {
    for (int s = -1; s <= 1; s += 2) {
      int b = (a + 1) % 3, c = (a + 2) % 3;
      if (s < 0) std::swap(b, c);
      double n[3] = {0, 0, 0};
      n[a] = s;
      uint32_t ids[4];
      const int corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
      for (int k = 0; k < 4; ++k) {
        double p[3];
        p[a] = s * h[a];
        p[b] = corners[k][0] * h[b];
        p[c] = corners[k][1] * h[c];
        ids[k] = add_vertex(&m, p[0], p[1], p[2], n[0], n[1], n[2]);
      }
      add_tri(&m, ids[0], ids[1], ids[2]);
      add_tri(&m, ids[0], ids[2], ids[3]);
    }
  }
  return m;
}

Mesh make_cylinder(double radius, double height, int slices) {
  Mesh m;
  // Side: two rings with radial normals.
  for (int ring = 0; ring < 2; ++ring) {
    for (int j = 0; j <= slices; ++j) {
      double th = 2 * kPi * double(j) / slices;
      double cx = std::cos(th), sy = std::sin(th);
      add_vertex(&m, radius * cx, radius * sy, ring * height, cx, sy, 0);
    }
  }
  for (int j = 0; j < slices; ++j) {
    uint32_t a = uint32_t(j), b = uint32_t(j + 1), c = uint32_t(slices + 1 + j), d = uint32_t(slices + 2 + j);
    add_tri(&m, a, b, d);
    add_tri(&m, a, d, c);
  }
  // Caps: a centre vertex plus a ring with the cap's flat normal.
  for (int cap = 0; cap < 2; ++cap) {
    double z = cap * height, nz = cap ? 1.0 : -1.0;
    uint32_t centre = add_vertex(&m, 0, 0, z, 0, 0, nz);
    uint32_t first = uint32_t(m.num_vertices());
    for (int j = 0; j <= slices; ++j) {
      double th = 2 * kPi * double(j) / slices;
      add_vertex(&m, radius * std::cos(th), radius * std::sin(th), z, 0, 0, nz);
    }
    for (int j = 0; j < slices; ++j) {
      if (cap) add_tri(&m, centre, first + j, first + j + 1);
      else add_tri(&m, centre, first + j + 1, first + j);
    }
  }
  return m;
}

Mesh make_torus(double major, double minor, int major_segments, int minor_segments) {
  Mesh m;
  for (int i = 0; i <= major_segments; ++i) {
    double u = 2 * kPi * double(i) / major_segments;
    double cu = std::cos(u), su = std::sin(u);
    for (int j = 0; j <= minor_segments; ++j) {
      double v = 2 * kPi * double(j) / minor_segments;
      double cv = std::cos(v), sv = std::sin(v);
      double r = major + minor * cv;
      add_vertex(&m, r * cu, r * su, minor * sv, cv * cu, cv * su, sv);
    }
  }
  auto at = [&](int i, int j) { return uint32_t(i * (minor_segments + 1) + j); };
  for (int i = 0; i < major_segments; ++i) {
    for (int j = 0; j < minor_segments; ++j) {
      add_tri(&m, at(i, j), at(i + 1, j), at(i + 1, j + 1));
      add_tri(&m, at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
  return m;
}

void place_mesh(Mesh* mesh, double yaw, const double translation[3]) {
  double c = std::cos(yaw), s = std::sin(yaw);
  for (size_t v = 0; v < mesh->num_vertices(); ++v) {
    float* p = &mesh->positions[3 * v];
    float* n = &mesh->normals[3 * v];
    double px = p[0], py = p[1], nx = n[0], ny = n[1];
    p[0] = float(c * px - s * py + translation[0]);
    p[1] = float(s * px + c * py + translation[1]);
    p[2] = float(p[2] + translation[2]);
    n[0] = float(c * nx - s * ny);
    n[1] = float(s * nx + c * ny);
  }
}

}  // namespace hbgs::synth::detail
