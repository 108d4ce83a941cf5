// Small 3-vector math for host and device (in the spirit of cuda-samples'
// helper_math.h). Float on the device; the same template in double for the
// reference computations of the tests.
#pragma once

#include <cfloat>
#include <cmath>
#include <type_traits>

#include "hd.h"

namespace sphray {

template <class T>
struct Vec3 {
  T x, y, z;
};

using Vec3f = Vec3<float>;
using Vec3d = Vec3<double>;
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f to_f(Vec3d v) { return {float(v.x), float(v.y), float(v.z)}; }

template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T> operator+(Vec3<T> a, Vec3<T> b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T> operator-(Vec3<T> a, Vec3<T> b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T> operator-(Vec3<T> a) { return {-a.x, -a.y, -a.z}; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T> operator*(Vec3<T> a, T s) { return {a.x * s, a.y * s, a.z * s}; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T> operator*(T s, Vec3<T> a) { return {a.x * s, a.y * s, a.z * s}; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T>& operator+=(Vec3<T>& a, Vec3<T> b) { a.x += b.x; a.y += b.y; a.z += b.z; return a; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T>& operator-=(Vec3<T>& a, Vec3<T> b) { a.x -= b.x; a.y -= b.y; a.z -= b.z; return a; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE T dot(Vec3<T> a, Vec3<T> b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE T length2(Vec3<T> a) { return dot(a, a); }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE T length(Vec3<T> a) { return std::sqrt(dot(a, a)); }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T> normalized(Vec3<T> a) { return a * (T(1) / std::sqrt(dot(a, a))); }
template <class T> SPHRAY_HD SPHRAY_FORCEINLINE Vec3<T> cross(Vec3<T> a, Vec3<T> b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

SPHRAY_HD SPHRAY_FORCEINLINE bool all_finite(Vec3f a) {
  return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

// The rows of R = Rz Ry Rx: a turn by a about x, then b about y, then c
// about z [radians] (the placement of meshes, mesh/mesh.h, and the motion
// of obstacles, sph/obstacles.h).
template <class T>
SPHRAY_HD SPHRAY_FORCEINLINE void rotation_rows_xyz(T a, T b, T c, Vec3<T> rows[3]) {
  const T cx = std::cos(a), sx = std::sin(a), cy = std::cos(b), sy = std::sin(b), cz = std::cos(c), sz = std::sin(c);
  rows[0] = {cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx};
  rows[1] = {sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx};
  rows[2] = {-sy, cy * sx, cy * cx};
}

// Ray o + t d against the box [lo, hi]: entry and exit distances t0 <= t1,
// false when missed or when the box lies wholly behind (t1 <= 0). Used by the
// raycaster (float, render/raycast.h) and the scene setup (double,
// pipeline/setup.cpp).
template <class T>
SPHRAY_HD SPHRAY_FORCEINLINE bool ray_box(Vec3<T> o, Vec3<T> d, Vec3<T> lo, Vec3<T> hi, T& t0, T& t1) {
  T a = T(-1e30), b = T(1e30);
  t0 = T(0);
  t1 = T(-1);
  const T oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z}, l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
  for (int k = 0; k < 3; ++k) {
    if (dd[k] == T(0)) {
      if (oo[k] < l[k] || oo[k] > h[k]) return false;
      continue;
    }
    const T inv = T(1) / dd[k];
    T ta = (l[k] - oo[k]) * inv, tb = (h[k] - oo[k]) * inv;
    if (ta > tb) { const T s = ta; ta = tb; tb = s; }
    a = ta > a ? ta : a;
    b = tb < b ? tb : b;
  }
  t0 = a;
  t1 = b;
  return b >= a && b > T(0);
}

// Four floats, 16-byte aligned, so one load fetches a particle's state on the GPU.
struct alignas(16) Float4 {
  float x, y, z, w;
};

SPHRAY_HD SPHRAY_FORCEINLINE Vec3f xyz(Float4 a) { return {a.x, a.y, a.z}; }

// Neighbour data is read-only within a stage: on the GPU, load it through the
// read-only data cache as one 16-byte load.
SPHRAY_HD SPHRAY_FORCEINLINE Float4 load(const Float4* p) {
#if defined(__CUDA_ARCH__)
  const float4 v = __ldg(reinterpret_cast<const float4*>(p));
  return {v.x, v.y, v.z, v.w};
#else
  return *p;
#endif
}

struct Aabb {
  Vec3f min, max;
};

// An axis-aligned box in double precision (tanks, fluid blocks).
struct Box {
  Vec3d min, max;
};

// 1/sqrt(x): one special-function instruction on the GPU (flushing
// subnormals; rsqrtf without the flush scales them, four more instructions).
SPHRAY_HD SPHRAY_FORCEINLINE float inv_sqrt(float x) {
#if defined(__CUDA_ARCH__)
  float y;
  asm("rsqrt.approx.ftz.f32 %0, %1;" : "=f"(y) : "f"(x));
  return y;
#else
  return 1.0f / std::sqrt(x);
#endif
}

// 1 / sqrt(x) for the neighbour loops, 0 where x has no usable root: in
// float inv_sqrt (one instruction on the GPU) from the smallest normal float
// up (below it inv_sqrt flushes to infinity), in double (the tests'
// references) the exact quotient for x > 0. x inv_sqrt_or_zero(x) is then
// sqrt(x), and 0 at x = 0, never a NaN.
template <class T>
SPHRAY_HD SPHRAY_FORCEINLINE T inv_sqrt_or_zero(T x) {
  if constexpr (std::is_same_v<T, float>) return x >= FLT_MIN ? inv_sqrt(x) : 0.0f;
  else return x > T(0) ? T(1) / std::sqrt(x) : T(0);
}

// sqrt(x) as x inv_sqrt(x): on the GPU one special-function instruction and
// a multiply instead of the IEEE sequence; 0 below the smallest normal float.
SPHRAY_HD SPHRAY_FORCEINLINE float fast_sqrt(float x) { return x * inv_sqrt_or_zero(x); }

}  // namespace sphray
