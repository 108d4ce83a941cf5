// Small 3-vector math for host and device (in the spirit of cuda-samples'
// helper_math.h). Float on the device; the same template in double for the
// reference computations of the tests.
#pragma once

#include <cmath>

#include "hd.h"

namespace sphray {

template <class T>
struct Vec3 {
  T x, y, z;
};

using Vec3f = Vec3<float>;
using Vec3d = Vec3<double>;

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

SPHRAY_HD SPHRAY_FORCEINLINE bool all_finite(Vec3f a) {
  return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

// Ray o + t d against the box [lo, hi]: entry and exit distances t0 <= t1,
// false when missed or when the box lies wholly behind (t1 <= 0). Used by the
// raycaster (float, cuda/render/raycast.h) and the scene setup (double,
// src/setup.cpp).
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

}  // namespace sphray
