// The cube map that carries waves over a closed genus-0 mesh (Kira,
// Nakayama & Fujishiro, "Visual Simulation of Wave Propagation Using
// Distortion-free Displacement Mapping", 2021): the mesh is mapped one to one
// onto the unit sphere, a cube around the sphere's centre is divided into
// texels, and each texel stores the point of the real surface that the ray
// through its centre meets on the sphere. Texels see their eight neighbours
// (across the cube's edges too) at their distances on the real surface, so a
// wave computed on the texels runs at the same speed over the surface
// wherever the texels are small or large ("distortion-free"). Host code only;
// sph/skin.h runs the waves.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/vec.h"
#include "mesh.h"

namespace sphray {

// One-to-one spherical embedding of a closed, outward-wound genus-0 mesh:
// a unit vector per vertex such that every triangle keeps its orientation on
// the sphere (no fold). The central projection from the mesh's centroid,
// where it folds no triangle (the mesh is star-shaped about its centroid);
// else the mesh is first rounded by conformalized mean-curvature flow
// (Kazhdan, Solomon & Ben-Chen 2012) until the projection of the rounded
// shape folds none. (Kira et al. use a conformal spherical map, FLASH; the
// waves need only a one-to-one map, since their distances are measured on
// the real surface.) Throws MeshError naming the mesh when folds remain
// after `max_iterations` flow steps.
struct SphereEmbedding {
  std::vector<Vec3d> u;   // per vertex, unit length
  Vec3d centre{0, 0, 0};  // the centroid of the shape projected
  int iterations = 0;     // flow steps run (0: the central projection of the mesh itself)
};
SphereEmbedding embed_on_sphere(const TriangleMesh& m, int max_iterations = 200);
// Triangles whose image on the sphere is folded (non-positive orientation).
size_t folded_triangles(const TriangleMesh& m, const std::vector<Vec3d>& u);

// Cube faces in the order +x, -x, +y, -y, +z, -z; a face's direction is
// axis + a tu + b tv with a, b in [-1, 1].
struct CubeCoord {
  int face = 0;
  double a = 0, b = 0;
};
CubeCoord cube_coord(Vec3d d);
Vec3d cube_direction(int face, double a, double b);

constexpr int kSkinNeighbours = 8;

struct SkinMap {
  int n = 0;  // texels along a cube edge; texel (face, i, j) is index (face n + j) n + i
  std::vector<Vec3d> point;   // per texel: the surface point, in the mesh's coordinates
  std::vector<Vec3d> normal;  // per texel: the outward normal of the triangle it lies in
  // Per texel: the eight neighbours (edge neighbours first, then diagonals;
  // across a cube edge through the neighbouring face) and their distances
  // on the real surface (straight-line, between the stored points).
  std::vector<std::array<uint32_t, kSkinNeighbours>> neighbour;
  std::vector<std::array<double, kSkinNeighbours>> distance;
  double mean_spacing = 0;  // mean distance to the four edge neighbours
  SphereEmbedding embedding;

  size_t size() const { return point.size(); }
  uint32_t index(int face, int i, int j) const { return uint32_t((face * n + j) * n + i); }
  // The texel whose square holds the direction d from the sphere's centre.
  uint32_t texel_of(Vec3d d) const;
  // A value per texel read at direction d: bilinear between the four texel
  // centres around it on its face (clamped to the face's outer centres).
  double sample(const std::vector<float>& value, Vec3d d) const;
};

// Over `embedding`, the mesh's embed_on_sphere (computed here when empty).
// Throws MeshError (naming the mesh) when it cannot be embedded; n >= 2.
SkinMap make_skin_map(const TriangleMesh& m, int n, SphereEmbedding embedding = {});

// The mesh split flat (each triangle into four at its edge midpoints) until no
// edge is longer than `max_edge`, at most `max_levels` times, with each new
// vertex's direction on the sphere (the normalised midpoint of its edge's,
// so that it lies where a texel ray through it meets the embedded mesh).
// The surface is unchanged; it only gains vertices to displace.
struct SkinSurface {
  TriangleMesh mesh;
  std::vector<Vec3d> direction;  // per vertex, on the sphere
  std::vector<Vec3d> normal;     // per vertex: area-weighted mean of its triangles' normals
};
SkinSurface skin_surface(const TriangleMesh& m, const SphereEmbedding& e, double max_edge, int max_levels = 6);

}  // namespace sphray
