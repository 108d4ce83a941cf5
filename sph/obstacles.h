// Triangle-mesh obstacles as the solvers see them: each step's motion of a
// particle, the segment from where it was to where the step puts it, is
// tested against the obstacles' BVHs (mesh/bvh.h); a particle whose segment
// crosses a triangle stops on the side it came from, `offset` off the
// surface, and loses the velocity component into it (Mishima et al.: the
// particle's path against the AABB tree, then the triangle). A thin plate
// therefore leaks no particle whatever the step. WCSPH's wall particles
// inside the meshes (pipeline/setup.cpp) push the liquid away before it
// gets there; PBF and DFSPH see the meshes only through this test.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "core/vec.h"
#include "mesh/bvh.h"

namespace sphray {

constexpr uint32_t kMaxObstacles = 8;

struct Obstacles {
  MeshView mesh[kMaxObstacles];
  uint32_t count = 0;
  float offset = 0;  // [m] kept between a stopped particle and the surface
};

// A mesh in world coordinates, as the solver input carries it.
struct MeshInput {
  std::vector<Vec3f> vertices;
  std::vector<uint32_t> indices;  // three per triangle
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
    set.view.mesh[set.view.count++] = set.trees.back()->view();
  }
  // Far above the rounding of single-precision positions (2^-24 m at 1 m),
  // far below the spacing.
  set.view.offset = 0.01f * spacing;
  return set;
}

// Moves `to` back out where the segment from -> to enters an obstacle (the
// first entry), and returns the outward unit normal there (zero when it
// enters none). One-sided: the liquid is outside every (closed, outward
// wound) mesh, so a segment enters through a triangle when it starts on its
// outer side, or within half the offset under it (a particle that rounding
// left on the surface), and ends under it; the crossing point must lie in
// the triangle (its edges widened by kEdgeSlack, so that shared edges leak
// nothing). A two-sided ray test would miss a particle that rests exactly
// on the surface, where the crossing's parameter rounds to zero.
SPHRAY_HD inline Vec3f stop_at_obstacles(const Obstacles& obs, Vec3f from, Vec3f& to) {
  Vec3f normal{0.0f, 0.0f, 0.0f};
  if (obs.count == 0) return normal;
  const Vec3f d = to - from;
  if (d.x == 0.0f && d.y == 0.0f && d.z == 0.0f) return normal;
  const float tol = 0.5f * obs.offset;
  float best = 2.0f;
  for (uint32_t k = 0; k < obs.count; ++k) {
    const MeshView& m = obs.mesh[k];
    for_each_leaf_along(m, from, d, 1.0f, tol, [&](uint32_t slot) {
      const BvhTriangle& t = m.tris[slot];
      const Vec3f v0 = xyz(t.v0), e1 = xyz(t.e1), e2 = xyz(t.e2);
      const Vec3f n = triangle_normal(t);
      const float d0 = dot(n, from - v0), d1 = dot(n, to - v0);
      if (d0 < -tol || d1 >= 0.0f) return 1.0f;  // not entering through this plane
      const float s = d0 > 0.0f ? d0 / (d0 - d1) : 0.0f;
      if (s >= best) return 1.0f;
      const Vec3f w = from + s * d - v0;
      const float d00 = dot(e1, e1), d01 = dot(e1, e2), d11 = dot(e2, e2), d20 = dot(w, e1), d21 = dot(w, e2);
      const float inv = 1.0f / (d00 * d11 - d01 * d01);
      const float b1 = (d11 * d20 - d01 * d21) * inv, b2 = (d00 * d21 - d01 * d20) * inv;
      if (b1 < -kEdgeSlack || b2 < -kEdgeSlack || b1 + b2 > 1.0f + kEdgeSlack) return 1.0f;
      best = s;
      normal = n;
      return 1.0f;
    });
  }
  if (best <= 1.0f) to = from + best * d + obs.offset * normal;
  return normal;
}

// v without its component into the surface of normal n (n zero: v).
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f slide_along(Vec3f v, Vec3f n) {
  const float vn = dot(v, n);
  return vn < 0.0f ? v - vn * n : v;
}

}  // namespace sphray
