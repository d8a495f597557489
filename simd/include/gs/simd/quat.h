// SPDX-License-Identifier: MIT
// The rotation matrix of a unit quaternion: the one formula of hbgs, used by the projection
// kernels (the scalar reference and the xsimd variants, on their own normalisation: a multiply by
// the reciprocal norm, the kernels' spec) and by the pose and IO code in double
// (gs::pose::rotation_from_quaternion: division by the norm). T is float, double or an xsimd batch;
// the expression is the same for all, so each caller keeps its exact float operation order.
#pragma once

namespace gs::simd {

// R = rotation of the unit quaternion (w, x, y, z), row-major [9]. Internal linkage (static): the
// per-ISA kernel translation units instantiate it on their own batch types, and no symbol may be
// shared between them outside their arch namespace (tests/simd/check_isa_symbols.sh; an unoptimised
// or sanitised build would otherwise emit weak copies).
template <class T>
static inline void rotmat_of_unit_quat(const T& w, const T& x, const T& y, const T& z, T R[9]) {
  const T one(1.0f), two(2.0f);
  R[0] = one - two * (y * y + z * z);
  R[1] = two * (x * y - w * z);
  R[2] = two * (x * z + w * y);
  R[3] = two * (x * y + w * z);
  R[4] = one - two * (x * x + z * z);
  R[5] = two * (y * z - w * x);
  R[6] = two * (x * z - w * y);
  R[7] = two * (y * z + w * x);
  R[8] = one - two * (x * x + y * y);
}

}  // namespace gs::simd
