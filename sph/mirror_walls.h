// The walls of a box tank as mirrors, for the incompressible solvers (PBF,
// pbf.h; DFSPH, dfsph.h): a particle within the support of a wall sees the
// mirror images of itself and of its neighbours across it (across two or
// three walls at an edge or a corner) as wall particles: PBF's carry their
// originals' lambdas (or none, pbf.images), DFSPH's their pressures. Images follow
// the liquid: a wall beside a free surface mirrors the surface (a half-space
// of liquid beyond each wall instead over-counts there and at corners).
// The walls are free-slip. After a step's positions change they are
// projected into the tank, so no particle leaves it.
#pragma once

#include <cmath>
#include <cstdint>

#include "mesh_walls.h"
#include "nsearch/pair_masks.h"
#include "params.h"

namespace sphray {

// The tank's planes within the support of a point, the nearer one per axis:
// the mirrors that make its wall images (Mirrors::images).
struct Mirrors {
  float plane[3];
  uint32_t axes = 0;   // bit a: a wall across axis a is within reach
  uint32_t upper = 0;  // bit a: that wall is the upper one (face 2a + 1, else 2a)

  // Calls f(image, set) for each image of p: reflected across every
  // non-empty subset of the walls in reach (one wall: 1 image; an edge: 3; a
  // corner: 7); bit a of set says the image is reflected across the wall of
  // axis a, so that a vector of the original (a velocity) is the image's
  // after flip(v, set). The subsets are enumerated directly (set = (set - 1)
  // & axes, from axes down), so the loop runs once per image: a loop over all
  // seven sets that skipped the others was unrolled on the GPU into seven
  // copies of the pass's pair physics per neighbour (PBF's near-wall Lambda
  // took 55 registers instead of 47, and a 1M PBF step 4% longer).
  template <class F>
  SPHRAY_HD SPHRAY_FORCEINLINE void images(Vec3f p, F&& f) const {
#if defined(__CUDA_ARCH__)
#pragma unroll 1
#endif
    for (uint32_t set = axes; set != 0u; set = (set - 1u) & axes) {
      Vec3f m = p;
      if (set & 1u) m.x = 2.0f * plane[0] - p.x;
      if (set & 2u) m.y = 2.0f * plane[1] - p.y;
      if (set & 4u) m.z = 2.0f * plane[2] - p.z;
      f(m, set);
    }
  }
  SPHRAY_HD SPHRAY_FORCEINLINE static Vec3f flip(Vec3f v, uint32_t set) {
    if (set & 1u) v.x = -v.x;
    if (set & 2u) v.y = -v.y;
    if (set & 4u) v.z = -v.z;
    return v;
  }
  // A velocity of the original as the image's for the viscous term: each
  // free-slip wall of the set reverses its normal component, each no-slip
  // wall (bit 2a + side of no_slip_faces) the whole velocity, so that the
  // mean of a particle and its image vanishes at a no-slip wall.
  SPHRAY_HD SPHRAY_FORCEINLINE Vec3f viscous_image(Vec3f v, uint32_t set, uint32_t no_slip_faces) const {
    for (uint32_t a = 0; a < 3; ++a) {
      if (!(set & (1u << a))) continue;
      if (no_slip_faces & (1u << (2 * a + ((upper >> a) & 1u)))) v = -1.0f * v;
      else v = flip(v, 1u << a);
    }
    return v;
  }
};

// The tank's planes within `reach` of x (inside the tank), the nearer one
// per axis; an open top is no mirror.
SPHRAY_HD SPHRAY_FORCEINLINE Mirrors mirrors_near(const Aabb& tank, bool open_top, float reach, Vec3f x) {
  Mirrors m;
  const float p[3] = {x.x, x.y, x.z};
  const float lo[3] = {tank.min.x, tank.min.y, tank.min.z};
  const float hi[3] = {tank.max.x, tank.max.y, tank.max.z};
  for (int a = 0; a < 3; ++a) {
    const float d_lo = p[a] - lo[a];
    const float d_hi = (a == 2 && open_top) ? reach : hi[a] - p[a];
    // An image lies at least as far as the wall: walls beyond the reach have none in it.
    const bool near_lo = d_lo < reach, near_hi = d_hi < reach;
    if (near_lo && (!near_hi || d_lo <= d_hi)) { m.plane[a] = lo[a]; m.axes |= 1u << a; }
    else if (near_hi) { m.plane[a] = hi[a]; m.axes |= 1u << a; m.upper |= 1u << a; }
    else m.plane[a] = 0.0f;
  }
  return m;
}

SPHRAY_HD SPHRAY_FORCEINLINE Mirrors mirrors_of(const SphParams& prm, float support, Vec3f x) {
  return mirrors_near(prm.tank, prm.open_top, support, x);
}

// x beyond a wall of the tank (an open top is none) reflected across it:
// across both walls of an edge and the three of a corner where x lies beyond them.
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f reflect_into(const Aabb& tank, bool open_top, Vec3f x) {
  if (x.x < tank.min.x) x.x = 2.0f * tank.min.x - x.x;
  else if (x.x > tank.max.x) x.x = 2.0f * tank.max.x - x.x;
  if (x.y < tank.min.y) x.y = 2.0f * tank.min.y - x.y;
  else if (x.y > tank.max.y) x.y = 2.0f * tank.max.y - x.y;
  if (x.z < tank.min.z) x.z = 2.0f * tank.min.z - x.z;
  else if (x.z > tank.max.z && !open_top) x.z = 2.0f * tank.max.z - x.z;
  return x;
}

// Registers per thread of the neighbour passes on the GPU
// (core/launch_cuda.cuh): the wall images' loop spills under the file-wide 40.
constexpr int kMirrorPassRegisters = 64;

// Each neighbour pass runs three variants of its loop, each particle served
// by one: the pair masks of the particles away from the walls (no image or
// wall particle code in the loop, which cost the interior particles twice
// the time when they carried it), the pair masks of those within a support
// of a wall of the tank or, in a scene with obstacles, near an obstacle's
// wall particles (mesh_walls.h), and the direct loop of those whose masks
// overflowed (nsearch/pair_masks.h). Which variant serves a particle is
// decided once per grid (launch_class); the first two run in one launch
// over lists of their particles, the near-wall ones first, and the direct
// loop in a small launch of its own (flow_solver.inl, LaunchLists). The
// near-wall variant is compiled without the obstacles' wall terms
// (kNearWalls) and with them (kNearMesh), and a scene runs the one it needs:
// carried in a scene without obstacles, their code made the launch 1-2%
// slower.
enum MirrorPass { kInterior = 0, kNearWalls = 1, kDirect = 2, kNearMesh = 3 };

// A pass with its flag fixed (presence, a solve's variant), as a template
// of the launch alone: the solvers launch every neighbour pass the same way
// (flow_solver.inl, mirror_pass_launches).
template <bool B, template <bool, int> class Pass>
struct WithFlag {
  template <int P>
  using pass = Pass<B, P>;
};

// The launch that serves a particle over the passes that share its grid.
enum LaunchClass : uint8_t { kClassInterior = 0, kClassNearWalls = 1, kClassDirect = 2 };

// The class of particle i at x, for passes over which it moves at most
// `margin` from x (PBF's corrections; 0 where the positions stay): near the
// walls if a wall of the tank lies within support + margin or the obstacles'
// wall particles may lie within two supports (their cell flags,
// WallsView::near_point), so that an interior particle meets neither in any
// of those passes. A margin of a support or more makes every particle near
// (the near-wall launch serves any particle; the cell flags reach only that
// far).
SPHRAY_HD SPHRAY_FORCEINLINE uint8_t launch_class(const SphParams& prm, float support, float margin,
                                                  const WallsView& walls, const PairMask& pairs, uint32_t i, Vec3f x) {
  if (!mask_complete(pairs, i)) return kClassDirect;
  if (margin >= support || mirrors_of(prm, support + margin, x).axes != 0u || walls.near_point(x))
    return kClassNearWalls;
  return kClassInterior;
}

// Whether launch P runs the obstacles' wall particle terms (for the particles it serves near them).
constexpr bool with_mesh_walls(int P) { return P == kNearMesh || P == kDirect; }

// The neighbour loop of launch P with the wall images: f(r, r2, a, set) for
// every neighbour j within the support s2 of particle i at xi (set 0, a =
// fetch(j, p_j), p_j its entry of pos), and, in the launches near walls, for every image within it of i
// itself (a = self) and of each neighbour (its a), set the walls it
// crosses (Mirrors::flip turns the original's vectors into the image's). The
// order of the terms is fixed: i's images first, then each neighbour followed
// by its images.
template <int P, class T, class Fetch, class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_neighbour_and_image(const GridGeom& grid, const uint32_t* offsets,
                                                               const PairMask& pairs, const Float4* pos, uint32_t i,
                                                               Vec3f xi, float s2, const Mirrors& mirrors, T self,
                                                               Fetch&& fetch, F&& f) {
  auto images = [&](Vec3f xo, const T& a) {
    mirrors.images(xo, [&](Vec3f m, uint32_t set) {
      const Vec3f r = xi - m;
      const float r2 = length2(r);
      if (r2 < s2) f(r, r2, a, set);
    });
  };
  if (P != kInterior) images(xi, self);
  for_each_pair<P == kDirect>(grid, offsets, pos, xi, s2, i, pairs, i, [&](uint32_t j, Float4 pj, Vec3f r, float r2) {
    const T a = fetch(j, pj);
    f(r, r2, a, 0u);
    if (P != kInterior && mirrors.axes) images(xyz(pj), a);
  });
}

}  // namespace sphray
