// The optics of the raycaster, for host and device: colours, reflection,
// Snell refraction, Schlick's Fresnel term (Schlick 1994), the faces of a box.
#pragma once

#include <cmath>

#include "core/hd.h"
#include "core/vec.h"

namespace sphray {

struct Rgb {
  float r, g, b;
};
SPHRAY_HD SPHRAY_FORCEINLINE Rgb operator*(Rgb a, Rgb b) { return {a.r * b.r, a.g * b.g, a.b * b.b}; }
SPHRAY_HD SPHRAY_FORCEINLINE Rgb operator*(Rgb a, float s) { return {a.r * s, a.g * s, a.b * s}; }
SPHRAY_HD SPHRAY_FORCEINLINE Rgb operator+(Rgb a, Rgb b) { return {a.r + b.r, a.g + b.g, a.b + b.b}; }

SPHRAY_HD SPHRAY_FORCEINLINE Vec3f reflect(Vec3f d, Vec3f n) { return d - n * (2.0f * dot(d, n)); }

// Snell refraction of unit d at unit normal n (facing against d), eta = n1 / n2.
// False on total internal reflection.
SPHRAY_HD SPHRAY_FORCEINLINE bool refract(Vec3f d, Vec3f n, float eta, Vec3f& out, float& cos_t) {
  const float cos_i = -dot(n, d);
  const float k = 1.0f - eta * eta * (1.0f - cos_i * cos_i);
  if (k < 0.0f) return false;
  cos_t = std::sqrt(k);
  out = d * eta + n * (eta * cos_i - cos_t);
  return true;
}

// Schlick's approximation; `cos_theta` is the cosine on the optically thinner
// side (the transmitted angle when leaving the denser medium).
SPHRAY_HD SPHRAY_FORCEINLINE float schlick(float n1, float n2, float cos_theta) {
  float r0 = (n1 - n2) / (n1 + n2);
  r0 *= r0;
  const float m = 1.0f - cos_theta;
  const float m2 = m * m;
  return r0 + (1.0f - r0) * m2 * m2 * m;
}

// Faces of an axis-aligned box are numbered 0..5 = -x +x -y +y -z +z.
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f face_normal(int face) {  // outward
  Vec3f n{0, 0, 0};
  const float s = (face & 1) ? 1.0f : -1.0f;
  if (face < 2) n.x = s; else if (face < 4) n.y = s; else n.z = s;
  return n;
}

// The face of [lo, hi] nearest to p (a point on or in the box), among the
// first `faces` of them (5: all but the top).
SPHRAY_HD SPHRAY_FORCEINLINE int nearest_face(Vec3f p, Vec3f lo, Vec3f hi, int faces = 6) {
  const float dist[6] = {p.x - lo.x, hi.x - p.x, p.y - lo.y, hi.y - p.y, p.z - lo.z, hi.z - p.z};
  int best = 0;
  for (int k = 1; k < faces; ++k) best = dist[k] < dist[best] ? k : best;
  return best;
}

}  // namespace sphray
