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

}  // namespace sphray
