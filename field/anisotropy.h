// Anisotropic kernels for the density field (Yu & Turk, "Reconstructing
// Surfaces of Particle-Based Fluids Using Anisotropic Kernels", 2013;
// docs/field.md): each particle's falloff is stretched along the local
// surface into an ellipsoid and centred on a smoothed position, so that a flat
// surface is flat instead of a layer of beads, and a thin sheet is a sheet.
//
// Per particle, over the neighbours j within the radius r (itself included),
// with weights w = 1 - (|x_j - x_i| / r)^3:
//   mean  m = sum w (x_j - x_i) / sum w
//   cov   C = sum w (x_j - x_i)(x_j - x_i)^T / sum w - m m^T = R diag(l) R^T
// sigma_k = sqrt(l_k), the smallest raised to sigma_max / stretch; the axis
// scales s_k = sigma_k / (s_1 s_2 s_3)^(1/3) keep the kernel's volume (an
// interior particle, whose neighbours surround it evenly, stays a sphere).
// Fewer than `min_neighbours` neighbours: a sphere. The kernel is
// f(|S^-1 R^T (v - c)|) with c = x_i + smoothing * m: the splat evaluates
// the quadratic form r2 = d^T A d, A = R diag(1 / s^2) R^T, in voxel units.
#pragma once

#include <cmath>
#include <cstdint>

// Eigen's fixed-size 3x3 closed-form eigensolver runs in host and device code.
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>  // cross

#include "core/hd.h"
#include "core/vec.h"
#include "nsearch/grid.h"
#include "sph/covariance.h"
#include "sph/mirror_walls.h"
#include "volume.h"

namespace sphray {

struct AnisotropyParams {
  float radius = 0;              // neighbourhood [m]
  float stretch = 4;             // largest / smallest axis, at most
  float smoothing = 0.9f;        // centre = x + smoothing * mean offset
  uint32_t min_neighbours = 8;   // fewer: a sphere
  // The tank's walls as mirrors (field.anisotropy.mirror_walls): a particle
  // within the radius of a wall sums its own and its neighbours' images
  // across it, so that the wall does not count as a free side: a sheet on a
  // wall or a layer in a corner keeps the form and centre it has in the open.
  FieldWalls walls;
};

// One particle's kernel in voxel units, stored as three Float4 per particle in
// [3][n] layout: {c.x, c.y, c.z, h.z}, {A_xx, A_yy, A_zz, A_xy}, {A_xz, A_yz, h.x, h.y}
// (c: centre, A: the quadratic form, h: the half-extent of the ellipsoid of
// unit radius along each axis, sqrt((R S^2 R^T)_aa)).
struct Ellipsoid {
  Vec3f centre;
  float axx, ayy, azz, axy, axz, ayz;
  Vec3f half;

  SPHRAY_HD SPHRAY_FORCEINLINE static Ellipsoid load(const Float4* e, uint32_t n, uint32_t p) {
    const Float4 a = e[p], b = e[n + p], c = e[2 * size_t(n) + p];
    return {{a.x, a.y, a.z}, b.x, b.y, b.z, b.w, c.x, c.y, {c.z, c.w, a.w}};
  }
  SPHRAY_HD SPHRAY_FORCEINLINE void store(Float4* e, uint32_t n, uint32_t p) const {
    e[p] = {centre.x, centre.y, centre.z, half.z};
    e[n + p] = {axx, ayy, azz, axy};
    e[2 * size_t(n) + p] = {axz, ayz, half.x, half.y};
  }
  // The mark of a particle the presence builder leaves out (EllipsoidPass):
  // a negative half-extent in the first Float4, the only one written.
  SPHRAY_HD SPHRAY_FORCEINLINE static void store_buried(Float4* e, uint32_t p) { e[p] = {0.0f, 0.0f, 0.0f, -1.0f}; }
  SPHRAY_HD SPHRAY_FORCEINLINE static bool is_buried(const Float4* e, uint32_t p) { return e[p].w < 0.0f; }
  SPHRAY_HD SPHRAY_FORCEINLINE float r2(float dx, float dy, float dz) const {
    return axx * dx * dx + ayy * dy * dy + azz * dz * dz + 2.0f * (axy * dx * dy + axz * dx * dz + ayz * dy * dz);
  }
};

// The unit eigenvector of the symmetric C for its eigenvalue l: the longest
// of the cross products of two rows of C - l I, which span the plane
// orthogonal to it; (1, 0, 0) where all three vanish (l is C's only
// eigenvalue). Ill-conditioned where l is nearly repeated, and only used
// where that does not matter (ellipsoid_axes).
SPHRAY_HD SPHRAY_FORCEINLINE Eigen::Vector3f eigenvector_of(const Eigen::Matrix3f& C, float l) {
  const Eigen::Matrix3f B = C - l * Eigen::Matrix3f::Identity();
  const Eigen::Vector3f r0 = B.row(0), r1 = B.row(1), r2 = B.row(2);
  const Eigen::Vector3f c01 = r0.cross(r1), c02 = r0.cross(r2), c12 = r1.cross(r2);
  const float n01 = c01.squaredNorm(), n02 = c02.squaredNorm(), n12 = c12.squaredNorm();
  Eigen::Vector3f v = n01 >= n02 ? c01 : c02;
  float n = n01 >= n02 ? n01 : n02;
  if (n12 > n) {
    v = c12;
    n = n12;
  }
  return n > 0.0f ? Eigen::Vector3f(v / std::sqrt(n)) : Eigen::Vector3f(1.0f, 0.0f, 0.0f);
}

// The kernel from a covariance (normalised units) and a neighbour count.
// Separate from the neighbour loop so that tests can check it alone.
// Eigen's closed form gives the eigenvalues; the forms A = R diag(1/s^2) R^T
// and R diag(s^2) R^T need only the eigenvectors of the smallest and the
// largest one: with l1 <= l2 <= l3 and v1, v3 theirs, R diag(f) R^T =
// f2 I + (f1 - f2) v1 v1^T + (f3 - f2) v3 v3^T. Each vector is ill-defined
// exactly where its coefficient vanishes (a repeated eigenvalue), so the
// form stays accurate. Eigen's own eigenvectors (computeDirect) pick a
// column by a run-time index, which on the GPU put 136 bytes per thread in
// local memory: the pass took 0.333 ms at 4M particles on the H100
// (docs/field.md).
SPHRAY_HD SPHRAY_FORCEINLINE void ellipsoid_axes(const AnisotropyParams& ap, const Eigen::Matrix3f& cov,
                                                 uint32_t neighbours, Ellipsoid& e) {
  float s[3] = {1.0f, 1.0f, 1.0f};
  Eigen::Vector3f v1 = Eigen::Vector3f::Zero(), v3 = Eigen::Vector3f::Zero();
  if (neighbours >= ap.min_neighbours && ap.stretch > 1.0f) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> es;
    es.computeDirect(cov, Eigen::EigenvaluesOnly);
    const Eigen::Vector3f l = es.eigenvalues();  // ascending
    const float top = std::sqrt(l(2) > 0.0f ? l(2) : 0.0f);
    if (top > 0.0f) {
      const float floor_sigma = top / ap.stretch;
      for (int k = 0; k < 3; ++k) {
        const float sig = std::sqrt(l(k) > 0.0f ? l(k) : 0.0f);
        s[k] = sig > floor_sigma ? sig : floor_sigma;
      }
      const float g = std::cbrt(s[0] * s[1] * s[2]);
      for (int k = 0; k < 3; ++k) s[k] /= g;
      v1 = eigenvector_of(cov, l(0));
      v3 = eigenvector_of(cov, l(2));
    }
  }
  auto form = [&](float f1, float f2, float f3) -> Eigen::Matrix3f {
    return f2 * Eigen::Matrix3f::Identity() + (f1 - f2) * (v1 * v1.transpose()) + (f3 - f2) * (v3 * v3.transpose());
  };
  const Eigen::Matrix3f A = form(1.0f / (s[0] * s[0]), 1.0f / (s[1] * s[1]), 1.0f / (s[2] * s[2]));
  const Eigen::Matrix3f M = form(s[0] * s[0], s[1] * s[1], s[2] * s[2]);
  e.axx = A(0, 0); e.ayy = A(1, 1); e.azz = A(2, 2);
  e.axy = A(0, 1); e.axz = A(0, 2); e.ayz = A(1, 2);
  e.half = {std::sqrt(M(0, 0)), std::sqrt(M(1, 1)), std::sqrt(M(2, 2))};
}

// What a particle's ellipsoid can reach before it is computed, in voxels:
// its centre lies less than smoothing * radius from the particle (the mean
// offset m of ellipsoid_of is a weighted mean of offsets shorter than the
// radius, and the particle's own weight keeps |m| < 1), and no half-extent
// of the unit ellipsoid, sqrt((R diag(s^2) R^T)_aa), exceeds the largest
// axis scale, at most stretch^(2/3) (the scales keep the volume, s1 s2 s3 =
// 1, and the smallest is at least the largest / stretch). So along any
// axis the box of radius r reaches at most shift + scale * r from the
// particle (a thousandth added for rounding).
struct EllipsoidBound {
  float shift = 0, scale = 1;
  static EllipsoidBound of(const AnisotropyParams& ap, const VolumeGeom& vol) {
    EllipsoidBound b;
    b.shift = 1.001f * ap.smoothing * ap.radius / vol.voxel + 1e-3f;
    b.scale = 1.001f * (ap.stretch > 1.0f ? std::cbrt(ap.stretch * ap.stretch) : 1.0f);
    return b;
  }
  SPHRAY_HD SPHRAY_FORCEINLINE float reach(float r) const { return shift + scale * r; }
};

// The ellipsoid of particle i at xi from its neighbour sums (sph/covariance.h).
SPHRAY_HD SPHRAY_FORCEINLINE Ellipsoid ellipsoid_of(const AnisotropyParams& ap, const VolumeGeom& vol, Vec3f xi,
                                                    const CovarianceSums& s) {
  const float iw = 1.0f / s.w;  // W >= 1: the particle itself
  const float mx = s.mx * iw, my = s.my * iw, mz = s.mz * iw;
  Eigen::Matrix3f cov;
  cov << s.sxx * iw - mx * mx, s.sxy * iw - mx * my, s.sxz * iw - mx * mz,
         s.sxy * iw - mx * my, s.syy * iw - my * my, s.syz * iw - my * mz,
         s.sxz * iw - mx * mz, s.syz * iw - my * mz, s.szz * iw - mz * mz;
  Ellipsoid e;
  ellipsoid_axes(ap, cov, uint32_t(s.count), e);
  const float shift = ap.smoothing * ap.radius;
  e.centre = vol.to_voxels(Vec3f{xi.x + shift * mx, xi.y + shift * my, xi.z + shift * mz});
  return e;
}

// The grid the anisotropy pass sorts the particles by (field_impl.inl), over
// the view grid's extent. The view's cells are two supports wide under PBF
// and DFSPH (4.2 spacings): its rows around a particle of a jittered block
// hold 522 candidates for the 108 neighbours within the default radius of 3
// spacings; in cells of half the radius the 25 rows around it, culled to
// the radius, hold 231 (tests/test_anisotropy.cpp; docs/field.md, "Cost of
// the ellipsoids"). No finer than a third of the view's cells, so that its
// slab table has at most 27 times the view's entries whatever the radius (at
// least half the radius: ComputeAnisotropy reads two rows out).
constexpr float kAnisotropyCellsPerRadius = 2.0f;
static_assert(kAnisotropyCellsPerRadius <= 2.0f, "ComputeAnisotropy reads two rows out: cells of at least half the radius");
inline GridGeom anisotropy_grid(const GridGeom& view, float radius) {
  const float half = radius / kAnisotropyCellsPerRadius, third = view.cell_size / 3.0f;
  const float cell = half > third ? half : third;
  auto cells = [&](int n) { return int(std::ceil(double(n) * view.cell_size / cell)); };
  return {view.origin, cell, cells(view.nx), cells(view.ny), cells(view.nz)};
}

// One thread per particle of a set sorted by a grid whose cells are at least
// half the radius wide (anisotropy_grid; or the view's): the weighted
// covariance of its neighbours (the 25 candidate rows of that grid culled to
// the radius), its kernel and centre. `order` maps the sorted index to the
// view's (null: the set is the view), where the kernel is stored.
struct ComputeAnisotropy {
  static constexpr int kSpan = 2;
  GridGeom grid;
  const uint32_t* fine_offsets;
  const Float4* pos;        // sorted by grid
  const uint32_t* order;    // sorted index -> the view's, or null
  uint32_t n;
  VolumeGeom vol;
  AnisotropyParams ap;
  Float4* out;  // [3][n], in the view's order

  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t particle(uint32_t t) const { return order ? order[t] : t; }
  SPHRAY_HD void operator()(uint32_t t) const { compute(t).store(out, n, particle(t)); }
  SPHRAY_HD Ellipsoid compute(uint32_t t) const {
    const Vec3f xi = xyz(pos[t]);
    const float inv_r = 1.0f / ap.radius;
    CovarianceSums s;
    auto add_image = [&](Vec3f p, uint32_t) {
      const float dx = (p.x - xi.x) * inv_r, dy = (p.y - xi.y) * inv_r, dz = (p.z - xi.z) * inv_r;
      s.add(dx, dy, dz, dx * dx + dy * dy + dz * dz);
    };
    // An image lies beyond the wall, no nearer to xi than its original: the
    // neighbours within the radius hold every image within it.
    const Mirrors mirrors = ap.walls.mirror ? mirrors_near(ap.walls.tank, ap.walls.open_top, ap.radius, xi) : Mirrors{};
    if (mirrors.axes != 0u) mirrors.images(xi, add_image);
    for (int row = 0; row < candidate_rows<kSpan>(); ++row) {
      uint32_t begin = 0, end = 0;
      if (!candidate_row<kSpan>(grid, fine_offsets, xi, row, begin, end, ap.radius)) continue;
      for (uint32_t j = begin; j < end; ++j) {
        if (j == t) continue;
        const Vec3f pj = xyz(pos[j]);
        const float dx = (pj.x - xi.x) * inv_r, dy = (pj.y - xi.y) * inv_r, dz = (pj.z - xi.z) * inv_r;
        const float q2 = dx * dx + dy * dy + dz * dz;
        if (!(q2 < 1.0f)) continue;
        s.add(dx, dy, dz, q2);
        if (mirrors.axes != 0u) mirrors.images(pj, add_image);
      }
    }
    return ellipsoid_of(ap, vol, xi, s);
  }
};

// The same kernels from sums the solver's neighbour loop left (ParticleView::covariance).
struct AnisotropyFromSums {
  const Float4* pos;
  const Float4* sums;  // [3][n]
  uint32_t n;
  VolumeGeom vol;
  AnisotropyParams ap;
  Float4* out;  // [3][n]
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t particle(uint32_t t) const { return t; }
  SPHRAY_HD void operator()(uint32_t i) const { compute(i).store(out, n, i); }
  SPHRAY_HD Ellipsoid compute(uint32_t i) const {
    return ellipsoid_of(ap, vol, xyz(pos[i]), CovarianceSums::load(sums, n, i));
  }
};

}  // namespace sphray
