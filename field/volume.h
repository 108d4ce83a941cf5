// The density volume and its metaball falloff (Yasuda, Harada & Kawaguchi,
// docs/references.md, sec. 4.2; docs/field.md has the derivation of every number).
//
// Geometry: the volume covers the SPH grid cells that overlap the tank, at
// 2^refine voxels per cell edge, so every voxel knows its SPH cell.
// Falloff: lengths in voxels. A particle at distance r contributes
//   f(r) = 1 / (r^2 + core^2) - 1 / (R^2 + core^2)   for r < R, else 0:
// inverse square, a finite core, and zero (continuously) at the influence
// radius R. The iso value is f(sqrt(3)/2): a lone particle's surface is a
// sphere of radius sqrt(3)/2 voxel, so the centre of the voxel that contains
// a particle is always inside the surface (the coarse fill's guarantee).
#pragma once

#include <cmath>
#include <cstdint>

#include "core/hd.h"
#include "core/vec.h"
#include "nsearch/grid.h"

namespace sphray {

struct FieldShape {
  float radius;      // R [voxels]
  float core2;       // core^2 [voxels^2]
  float offset;      // 1 / (R^2 + core^2): f(R) = 0
  float iso;         // f(sqrt(3) / 2): the surface
  float coarse;      // the coarse fill's "just above the iso value"
  float clip;        // saturation: the presence builder never goes past it
  float min_extent;  // presence builder: extent of a fully surrounded side [voxels]
  float shrink_from; // presence builder: a side keeps its full extent up to this presence

  // Presence builder: half-extent of the splat toward a side with presence P:
  // R up to P = shrink_from, then linearly down to min_extent at P = 1.
  SPHRAY_HD SPHRAY_FORCEINLINE float extent(float P) const {
    float s = (P - shrink_from) / (1.0f - shrink_from);
    s = s < 0.0f ? 0.0f : (s > 1.0f ? 1.0f : s);
    return radius - (radius - min_extent) * s;
  }

  SPHRAY_HD SPHRAY_FORCEINLINE float falloff(float r2) const {
    return r2 < radius * radius ? 1.0f / (r2 + core2) - offset : 0.0f;
  }
};

// The tank's walls as mirrors for the field's neighbour sums (Zhu & Bridson's
// weighted mean, the ellipsoids' covariance): a point within reach of a wall
// sees the particles' images across it (across both walls of an edge and the
// three of a corner, as the solvers' mirrored images: sph/mirror_walls.h).
struct FieldWalls {
  bool mirror = false;  // off: no images
  bool open_top = false;
  Aabb tank{};  // the fluid side of the tank's walls [m]
};

// Zhu & Bridson's surface instead of a sum of falloffs (FieldKernel::ZhuBridson;
// builders.h, ZhuBridsonGather).
struct ZhuBridsonParams {
  // A lone particle's radius [voxels], whatever r: sqrt(3)/2 and a margin, so
  // that the centre of the voxel holding it is inside and trilinear sampling,
  // which shrinks a ball by up to a quarter voxel, never loses it.
  static constexpr float kLoneRadius = 0.95f;
  float radius = 0;           // R: the neighbours' reach [voxels]
  float particle_radius = 0;  // r: the surface's distance from their weighted mean [voxels]
  // The tank's walls as mirrors (field.zhu_bridson.mirror_walls): a voxel
  // within R of a wall sums the particles' images across it as well, and a
  // voxel beyond a wall takes the value at its mirror image inside. At a wall
  // the weighted mean then lies on the wall's plane, and the liquid's surface
  // meets the wall at a right angle; without the images it pulls back from
  // the wall as from a free side.
  using Walls = FieldWalls;
  Walls walls;
  // A lone particle's radius for r: r, or kLoneRadius where r is smaller.
  static constexpr float lone_radius_of(float r) { return r > kLoneRadius ? r : kLoneRadius; }

  // The surface's distance from the weighted mean at a voxel whose weights
  // sum to w (each particle's at most 1): r from four particles' worth of
  // weight up, the lone radius at two and below (a lone particle or a pair,
  // which a ball of r below sqrt(3)/2 could leave between the voxel
  // centres), linear between. A voxel centre half a spacing above a flat
  // lattice's top layer sees about nine, one and a half spacings above it
  // 2.3: the ramp reaches only the voxels beyond a liquid's surface, and r
  // places that surface (docs/field.md).
  SPHRAY_HD SPHRAY_FORCEINLINE float radius_at(float w) const {
    float t = 0.5f * (4.0f - w);
    t = t < 0.0f ? 0.0f : (t > 1.0f ? 1.0f : t);
    return particle_radius + t * (lone_radius_of(particle_radius) - particle_radius);
  }
};

struct VolumeGeom {
  Vec3f origin;   // world position of voxel (0,0,0)'s min corner [m]
  float voxel;    // edge [m] = grid cell / 2^refine
  int nx, ny, nz;
  int refine;     // voxels per cell edge = 1 << refine
  int cell0[3];   // SPH grid cell of voxel (0,0,0)

  SPHRAY_HD SPHRAY_FORCEINLINE uint64_t num_voxels() const { return uint64_t(nx) * uint64_t(ny) * uint64_t(nz); }
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t index(int i, int j, int k) const {
    return (uint32_t(k) * uint32_t(ny) + uint32_t(j)) * uint32_t(nx) + uint32_t(i);
  }
  // Position in voxel units (voxel centres at integer + 0.5).
  SPHRAY_HD SPHRAY_FORCEINLINE Vec3f to_voxels(Vec3f p) const {
    const float s = 1.0f / voxel;
    return {(p.x - origin.x) * s, (p.y - origin.y) * s, (p.z - origin.z) * s};
  }
  // The SPH grid key of voxel (i, j, k).
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t cell_key(const GridGeom& g, int i, int j, int k) const {
    const int cx = cell0[0] + (i >> refine), cy = cell0[1] + (j >> refine), cz = cell0[2] + (k >> refine);
    return (uint32_t(cz) * uint32_t(g.ny) + uint32_t(cy)) * uint32_t(g.nx) + uint32_t(cx);
  }
};

// Voxels whose centres lie in [u - lo, u + hi] along one axis, clamped to [0, n).
SPHRAY_HD SPHRAY_FORCEINLINE void voxel_span(float u, float lo, float hi, int n, int& first, int& last) {
  first = int(std::ceil(u - lo - 0.5f));
  last = int(std::floor(u + hi - 0.5f));
  if (first < 0) first = 0;
  if (last > n - 1) last = n - 1;
}

}  // namespace sphray
