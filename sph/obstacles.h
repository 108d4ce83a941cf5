// Triangle-mesh obstacles as the solvers see them: each step's motion of a
// particle, the segment from where it was to where the step puts it, is
// tested against the obstacles' BVHs (mesh/bvh.h); a particle whose segment
// crosses a triangle stops on the side it came from, `offset` off the
// surface, and loses the velocity component into it (Mishima et al.: the
// particle's path against the AABB tree, then the triangle). A thin plate
// therefore leaks no particle whatever the step. The wall particles inside
// the meshes (pipeline/setup.cpp; a moving mesh's move with it) push the
// liquid away before it gets there (WCSPH: boundary.h; PBF and DFSPH:
// mesh_walls.h). A moving mesh follows a prescribed rigid
// motion (Motion); the test runs in the mesh's own frame, the path's start
// taken back through the mesh's pose at the step's start and its end
// through the pose at its end, so the mesh's own sweep is part of the path.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/vec.h"
#include "mesh/bvh.h"

namespace sphray {

constexpr uint32_t kMaxObstacles = 8;
constexpr uint8_t kStaticWall = 0xFF;  // a wall particle that does not move

// A rigid pose: world = R body + t (R's rows in r).
struct RigidFrame {
  Vec3f r[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Vec3f t{0, 0, 0};
  SPHRAY_HD Vec3f dir_to_world(Vec3f d) const { return {dot(r[0], d), dot(r[1], d), dot(r[2], d)}; }
  SPHRAY_HD Vec3f to_world(Vec3f p) const { return dir_to_world(p) + t; }
  SPHRAY_HD Vec3f dir_to_body(Vec3f d) const { return r[0] * d.x + r[1] * d.y + r[2] * d.z; }
  SPHRAY_HD Vec3f to_body(Vec3f p) const { return dir_to_body(p - t); }
};

// A prescribed oscillation about the placed mesh (the pose at t = 0):
// with s = sin(omega t), the mesh turns by the angles s rotate about x, then
// y, then z around `pivot` and moves by s translate. omega = 0: static.
struct Motion {
  float omega = 0;       // 2 pi / period [1/s]
  Vec3f translate{0, 0, 0};  // amplitude [m]
  Vec3f rotate{0, 0, 0};     // amplitude [rad]
  Vec3f pivot{0, 0, 0};
  SPHRAY_HD bool moves() const { return omega != 0.0f; }
  SPHRAY_HD RigidFrame at(float time) const {
    RigidFrame f;
    if (omega == 0.0f) return f;
    const float s = std::sin(omega * time);
    rotation_rows_xyz(s * rotate.x, s * rotate.y, s * rotate.z, f.r);
    f.t = pivot + translate * s - f.dir_to_world(pivot);
    return f;
  }
};

struct Obstacles {
  MeshView mesh[kMaxObstacles];  // in the placed (t = 0) pose
  Motion motion[kMaxObstacles];
  uint32_t count = 0;
  float offset = 0;  // [m] kept between a stopped particle and the surface
  float time = 0;    // [s] the step's start (the solver sets it before each step)
};

// A mesh in world coordinates (placed: its pose at t = 0), as the solver
// input carries it, with its motion.
struct MeshInput {
  std::vector<Vec3f> vertices;
  std::vector<uint32_t> indices;  // three per triangle
  Motion motion{};
};

// The trees of a solver's obstacles on its backend and the view its kernels take.
struct ObstacleSet {
  std::vector<std::unique_ptr<Bvh>> trees;
  Obstacles view;
};

inline ObstacleSet make_obstacle_set(Backend backend, const std::vector<MeshInput>& meshes, float spacing) {
  ObstacleSet set;
  for (const MeshInput& m : meshes) {
    set.trees.push_back(make_bvh(backend, m.vertices, m.indices));
    set.view.motion[set.view.count] = m.motion;
    set.view.mesh[set.view.count++] = set.trees.back()->view();
  }
  // Far above the rounding of single-precision positions (2^-24 m at 1 m),
  // far below the spacing.
  set.view.offset = 0.01f * spacing;
  return set;
}

// What stopping a path found: the outward unit normal where it entered
// (zero when it entered nothing) and the mesh's own velocity there.
struct Stop {
  Vec3f normal{0, 0, 0};
  Vec3f wall_velocity{0, 0, 0};
  SPHRAY_HD bool hit() const { return normal.x != 0.0f || normal.y != 0.0f || normal.z != 0.0f; }
};

// Moves `to` back out where the segment from -> to, from time t0 to t1,
// enters an obstacle (the first entry). One-sided: the liquid is outside
// every (closed, outward wound) mesh, so a segment enters through a triangle
// when it starts on its outer side, or within half the offset under it (a
// particle that rounding left on the surface), and ends under it; the
// crossing point must lie in the triangle (its edges widened by
// kEdgeSlack, so that shared edges leak nothing). A two-sided ray test would
// miss a particle that rests exactly on the surface, where the crossing's
// parameter rounds to zero. A moving mesh is met in its own frame: `from`
// through its pose at t0, `to` through its pose at t1. Where a face lies in
// a tank wall's plane the stop puts `to` outside the tank by the offset:
// the callers project it back (inside_tank), or the next path, starting
// outside the face's edge, would miss the face beside it.
SPHRAY_HD inline Stop stop_at_obstacles(const Obstacles& obs, Vec3f from, Vec3f& to, float t0, float t1) {
  Stop stop;
  if (obs.count == 0) return stop;
  const float tol = 0.5f * obs.offset;
  float best = 2.0f;
  uint32_t best_k = 0;
  Vec3f best_nb{0, 0, 0}, best_fb{0, 0, 0}, best_db{0, 0, 0};
  for (uint32_t k = 0; k < obs.count; ++k) {
    const MeshView& m = obs.mesh[k];
    const bool moves = obs.motion[k].moves();
    const Vec3f fb = moves ? obs.motion[k].at(t0).to_body(from) : from;
    const Vec3f tb = moves ? obs.motion[k].at(t1).to_body(to) : to;
    const Vec3f d = tb - fb;
    if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) continue;
    for_each_leaf_along(m, fb, d, 1.0f, tol, [&](uint32_t slot) {
      const BvhTriangle& t = m.tris[slot];
      const Vec3f v0 = xyz(t.v0), e1 = xyz(t.e1), e2 = xyz(t.e2);
      const Vec3f n = triangle_normal(t);
      const float d0 = dot(n, fb - v0), d1 = dot(n, tb - v0);
      if (d0 < -tol || d1 >= 0.0f) return 1.0f;  // not entering through this plane
      const float s = d0 > 0.0f ? d0 / (d0 - d1) : 0.0f;
      if (s >= best) return 1.0f;
      const Vec3f w = fb + s * d - v0;
      const float d00 = dot(e1, e1), d01 = dot(e1, e2), d11 = dot(e2, e2), d20 = dot(w, e1), d21 = dot(w, e2);
      const float inv = 1.0f / (d00 * d11 - d01 * d01);
      const float b1 = (d11 * d20 - d01 * d21) * inv, b2 = (d00 * d21 - d01 * d20) * inv;
      if (b1 < -kEdgeSlack || b2 < -kEdgeSlack || b1 + b2 > 1.0f + kEdgeSlack) return 1.0f;
      best = s;
      best_k = k;
      best_nb = n;
      best_fb = fb;
      best_db = d;
      return 1.0f;
    });
  }
  if (best > 1.0f) return stop;
  const Vec3f pb = best_fb + best * best_db + obs.offset * best_nb;  // in the mesh's frame
  const Motion& mo = obs.motion[best_k];
  if (!mo.moves()) {
    to = pb;
    stop.normal = best_nb;
    return stop;
  }
  const RigidFrame f1 = mo.at(t1);
  to = f1.to_world(pb);
  stop.normal = f1.dir_to_world(best_nb);
  if (t1 > t0) stop.wall_velocity = (to - mo.at(t0).to_world(pb)) * (1.0f / (t1 - t0));
  return stop;
}

// v without its component into the surface of normal n (n zero: v).
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f slide_along(Vec3f v, Vec3f n) {
  const float vn = dot(v, n);
  return vn < 0.0f ? v - vn * n : v;
}

// v after a stop: the component into the surface, relative to the surface's
// own motion, removed (a moving mesh carries the particle along its normal).
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f velocity_after(Vec3f v, const Stop& stop) {
  return stop.hit() ? stop.wall_velocity + slide_along(v - stop.wall_velocity, stop.normal) : v;
}

}  // namespace sphray
