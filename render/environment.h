// What the raycaster looks at besides the liquid, for host and device: a
// pinhole camera, and the surroundings that make refraction visible. The tank
// is a box with an open top, glass toward the camera (not drawn), a tiled
// floor and tiled walls; outside it a large checker ground and a procedural
// sky with a sun. All in voxel units (the tracer's frame, raycast.h).
#pragma once

#include <cmath>
#include <cstdint>

#include "core/hd.h"
#include "core/vec.h"
#include "optics.h"

namespace sphray {

// Pinhole camera: pixel (x, y), row 0 at the top, to a unit world direction.
struct Camera {
  Vec3f eye, forward, right, up;  // orthonormal; up is the image's up
  float tan_half_fov;             // vertical
  int width, height;

  SPHRAY_HD SPHRAY_FORCEINLINE Vec3f direction(float px, float py) const {
    const float aspect = float(width) / float(height);
    const float sx = (2.0f * px / float(width) - 1.0f) * tan_half_fov * aspect;
    const float sy = (1.0f - 2.0f * py / float(height)) * tan_half_fov;
    return normalized(forward + right * sx + up * sy);
  }
};

// The surroundings, in voxel units (the tracer's frame).
struct Environment {
  Vec3f tank_lo, tank_hi;  // the tank's inner box
  float tile;              // floor and wall tile edge [voxels]
  Vec3f sun;               // unit direction toward the sun
  int glass;               // walls drawn as clear glass: bit f for face f (0..3 = -x +x -y +y)

  SPHRAY_HD SPHRAY_FORCEINLINE Rgb sky(Vec3f d) const {
    const float up = d.z < 0.0f ? 0.0f : d.z;
    const Rgb horizon{0.80f, 0.87f, 0.95f}, zenith{0.22f, 0.42f, 0.78f};
    const float s = std::sqrt(up);
    Rgb c = horizon * (1.0f - s) + zenith * s;
    const float cs = dot(d, sun);
    if (cs > 0.0f) {  // a soft glow and a small bright disc
      const float g = cs * cs * cs * cs;
      c = c + Rgb{1.0f, 0.9f, 0.7f} * (0.25f * g * g * g * g);
      if (cs > 0.9995f) c = c + Rgb{6.0f, 5.5f, 4.5f};
    }
    return c;
  }

  // Tiles with dark grout lines; a checker of two tints.
  SPHRAY_HD SPHRAY_FORCEINLINE Rgb tiles(float u, float v, Rgb a, Rgb b) const {
    const float fu = u / tile, fv = v / tile;
    const float iu = std::floor(fu), iv = std::floor(fv);
    const float gu = fu - iu, gv = fv - iv;
    const float grout = 0.04f;
    if (gu < grout || gv < grout) return Rgb{0.18f, 0.18f, 0.2f};
    return (int(iu) + int(iv)) & 1 ? a : b;
  }

  // Face of the tank box through which the ray p + t d (p inside) leaves,
  // 0..5 = -x +x -y +y -z +z, and its distance.
  SPHRAY_HD SPHRAY_FORCEINLINE int exit_face(Vec3f p, Vec3f d, float& t) const {
    const float dd[3] = {d.x, d.y, d.z}, pp[3] = {p.x, p.y, p.z};
    const float lo[3] = {tank_lo.x, tank_lo.y, tank_lo.z}, hi[3] = {tank_hi.x, tank_hi.y, tank_hi.z};
    int face = 5;
    t = 1e30f;
    for (int k = 0; k < 3; ++k) {
      if (dd[k] == 0.0f) continue;
      const float tk = ((dd[k] > 0.0f ? hi[k] : lo[k]) - pp[k]) / dd[k];
      if (tk < t) { t = tk; face = 2 * k + (dd[k] > 0.0f ? 1 : 0); }
    }
    if (t < 0.0f) t = 0.0f;
    return face;
  }
  // Where liquid can be: inside the walls and above the floor, at any height
  // (splashes rise above the rim). Outside, in the volume's margin, the field
  // only holds the spill-over of particles next to a wall.
  SPHRAY_HD SPHRAY_FORCEINLINE bool within_walls(Vec3f p) const {
    const float e = 1e-3f * tile;
    return p.x >= tank_lo.x - e && p.y >= tank_lo.y - e && p.z >= tank_lo.z - e && p.x <= tank_hi.x + e &&
           p.y <= tank_hi.y + e;
  }
  // The floor and the walls that are not glass stop rays (the open top does not).
  SPHRAY_HD SPHRAY_FORCEINLINE bool opaque(int face) const { return face == 4 || (face < 4 && !((glass >> face) & 1)); }
  SPHRAY_HD SPHRAY_FORCEINLINE bool in_tank(Vec3f p) const { return within_walls(p) && p.z <= tank_hi.z + 1e-3f * tile; }

  SPHRAY_HD Rgb outside(Vec3f p, Vec3f d) const {
    const Rgb ga{0.42f, 0.4f, 0.38f}, gb{0.3f, 0.29f, 0.28f};
    if (p.z < tank_lo.z) return tiles(p.x, p.y, ga, gb);  // under the floor (the volume's margin)
    if (d.z < 0.0f) {  // the ground around the tank, fading into the haze
      const float t = (tank_lo.z - p.z) / d.z;
      const Vec3f q = p + d * t;
      const float fade = 1.0f / (1.0f + 0.002f * t / tile);
      return tiles(q.x, q.y, ga, gb) * fade + sky(Vec3f{d.x, d.y, -d.z}) * (0.5f * (1.0f - fade));
    }
    return sky(d);
  }

  SPHRAY_HD Rgb operator()(Vec3f p, Vec3f d) const {
    float t0, t1;
    if (!ray_box(p, d, tank_lo, tank_hi, t0, t1)) return outside(p, d);
    // Through the tank: the glass faces (toward the viewer) are not drawn;
    // the ray stops on the floor or an opaque wall, or leaves through the
    // glass or the open top.
    Vec3f q = p + d * (t0 > 0.0f ? t0 : 0.0f);
    if (t0 > 0.0f) {  // entering from outside: through the top or glass only, else that face is seen
      float tt;
      const int enter = exit_face(q - d * (2e-3f * tile), -d, tt);  // the face the ray came in through
      if (enter == 4 || (enter < 4 && opaque(enter))) return outside(p, d);  // the tank's outer side: like the ground
    }
    float t;
    const int face = exit_face(q, d, t);
    const Vec3f e = q + d * t;
    return opaque(face) ? surface(face, e, d) : outside(e, d);
  }

  // The tiles of an opaque face at e, seen along d.
  SPHRAY_HD Rgb surface(int face, Vec3f e, Vec3f d) const {
    const float light = 0.55f + 0.45f * (d.z < 0.0f ? -d.z : 0.0f);  // a little darker at grazing angles
    if (face == 4) return tiles(e.x, e.y, Rgb{0.95f, 0.95f, 0.92f}, Rgb{0.25f, 0.45f, 0.75f}) * light;
    const Rgb wa{0.85f, 0.82f, 0.75f}, wb{0.65f, 0.62f, 0.55f};
    return (face < 2 ? tiles(e.y, e.z, wa, wb) : tiles(e.x, e.z, wa, wb)) * 0.8f;
  }
};

}  // namespace sphray
