// Waves on an obstacle's skin (Kira, Nakayama & Fujishiro, "Visual
// Simulation of Wave Propagation Using Distortion-free Displacement Mapping",
// 2021): a height per texel of the obstacle's cube map (mesh/skin_map.h)
// obeys a damped wave equation on an elastic foundation, driven by the
// pressure of the liquid on the surface,
//
//   d2h/dt2 = s^2 lap(h) - w0^2 h - zeta dh/dt - w0^2 C p,
//
// h the displacement along the outward normal [m], s the wave speed, w0 =
// 2 pi f0 the foundation's frequency, zeta the damping rate and C the
// compliance (a steady pressure p dents the skin by C p). The Laplacian
// takes each texel's eight neighbours at their positions on the real
// surface, which removes the cube map's distortion: by default as the paper
// does, edge neighbours 2/3 and diagonals 1/3 over their distances squared
// (exact for quadratics on a square grid only), or with weights fitted to
// those positions (SkinStencil). p is sampled per texel after every solver step from the
// fluid particles within one support (Shepard average, with the hydrostatic
// extrapolation of Adami et al. 2012 to the surface point); a texel with
// little liquid near it (kernel sum below kSkinCover) sees a proportionally
// smaller pressure, a dry one none. Steps are symplectic Euler, the damping
// implicit, substepped below the stencil's stability limit.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/atomics.h"
#include "core/device.h"
#include "core/vec.h"
#include "mesh/skin_map.h"
#include "nsearch/grid.h"
#include "params.h"
#include "skin_params.h"
#include "solver.h"

namespace sphray {

// The kernel sum (of V W over the fluid particles) of a texel wholly wet: about
// half of a full neighbourhood's 1, the liquid lying on one side of the surface.
constexpr float kSkinCover = 0.25f;

// The pressure at each texel's surface point [Pa], from the fluid particles
// sorted on `grid` (pos: x, y, z, density; pressure per particle): one
// element per texel and candidate row of the grid (nsearch/grid.h), adding
// its part of the kernel-weighted sums into sum[2 i] (pressure) and
// sum[2 i + 1] (weights), which start at zero; SkinLoadOf divides. (Skins
// have few texels, each with a few hundred candidates: a thread per texel
// alone would leave most of the device idle.)
struct SampleSkinLoad {
  const Vec3f* point;  // per texel, in the obstacle's placed frame
  RigidFrame pose;     // the obstacle's pose now
  GridGeom grid;
  const uint32_t* fine_offsets;
  const Float4* pos;
  const float* pressure;
  SmoothingKernel<float> kernel;
  float mass;
  Vec3f gravity;
  float* sum;
  SPHRAY_HD void operator()(uint32_t e) const {
    const uint32_t i = e / kCandidateRows;
    const int row = int(e % kCandidateRows);
    const Vec3f x = pose.to_world(point[i]);
    uint32_t begin = 0, end = 0;
    if (!candidate_row(grid, fine_offsets, x, row, begin, end) || begin == end) return;
    const float r_max = kernel.support(), r2_max = r_max * r_max;
    float num = 0.0f, den = 0.0f;
    for (uint32_t j = begin; j < end; ++j) {
      const Float4 q = pos[j];
      const Vec3f r = x - xyz(q);
      const float r2 = dot(r, r);
      if (r2 >= r2_max) continue;
      const float w = kernel.W(std::sqrt(r2)) * mass / q.w;
      num += w * (pressure[j] + q.w * dot(gravity, r));
      den += w;
    }
    if (den == 0.0f) return;
    atomic_add(&sum[2 * i], num);
    atomic_add(&sum[2 * i + 1], den);
  }
};

struct SkinLoadOf {
  float* sum;  // zeroed for the next sampling
  float* load;
  SPHRAY_HD void operator()(uint32_t i) const {
    const float num = sum[2 * i], den = sum[2 * i + 1];
    const float p = num / (den > kSkinCover ? den : kSkinCover);
    load[i] = p > 0.0f ? p : 0.0f;  // the liquid pushes; it does not pull
    sum[2 * i] = 0.0f;
    sum[2 * i + 1] = 0.0f;
  }
};

// One substep, first half: the new velocity of every texel from the heights.
struct SkinAccelerate {
  const float* h;
  float* v;
  const float* load;
  const uint32_t* neighbour;  // kSkinNeighbours per texel
  const float* coef;          // s^2 c_q / d_q^2 per neighbour
  float omega2, gain, zeta, dt;  // gain = w0^2 C
  SPHRAY_HD void operator()(uint32_t i) const {
    const float hi = h[i];
    float lap = 0.0f;
    for (int q = 0; q < kSkinNeighbours; ++q)
      lap += coef[i * kSkinNeighbours + q] * (h[neighbour[i * kSkinNeighbours + q]] - hi);
    const float a = lap - omega2 * hi - gain * load[i];
    v[i] = (v[i] + dt * a) / (1.0f + zeta * dt);
  }
};

// Second half: the heights from the new velocities.
struct SkinMove {
  float* h;
  const float* v;
  float dt;
  SPHRAY_HD void operator()(uint32_t i) const { h[i] += dt * v[i]; }
};

// The largest |h| (infinity for a non-finite one): the guard against waves
// that grow without bound.
struct SkinAbsHeight {
  const float* h;
  SPHRAY_HD float operator()(uint32_t i) const {
    const float a = h[i] < 0.0f ? -h[i] : h[i];
    return a == a ? a : INFINITY;
  }
};
struct SkinMax {
  SPHRAY_HD float operator()(float a, float b) const { return a > b ? a : b; }
};
// Every this many advances the largest height is checked (one reduction and
// read-back): beyond a quarter of the obstacle's size the run stops
// (SimulationError) rather than draw a skin blown apart.
constexpr int kSkinCheckEvery = 64;

// Host-side geometry of a skin: its cube map, the render surface that the
// heights displace, and the per-texel arrays the kernels read.
struct SkinGeometry {
  SkinInput input;
  SkinMap map;
  SkinSurface surface;
  std::vector<Vec3f> point;        // per texel, float
  std::vector<uint32_t> neighbour;  // kSkinNeighbours per texel
  std::vector<float> coef;          // kSkinNeighbours per texel
  double max_substep = 0;           // [s] the explicit scheme's stability limit, with margin
  size_t unfitted = 0;              // texels of a Fitted stencil left with the paper's weights
  double size = 0;                  // the mesh's bounding-box diagonal [m]
};
SkinGeometry make_skin_geometry(const SkinInput& in);
// The skin's render surface displaced by heights h (one per texel) along
// its vertices' normals, in the placed pose (mesh coordinates).
std::vector<Vec3f> displaced_surface(const SkinGeometry& g, const std::vector<float>& h);

// Every skin of a run on one backend.
class SkinSet {
 public:
  virtual ~SkinSet() = default;
  size_t size() const { return geo_.size(); }
  const SkinGeometry& geometry(size_t k) const { return geo_[k]; }
  const std::vector<SkinGeometry>& geometries() const { return geo_; }
  // Samples the liquid's pressure on every texel (the particles as a step
  // left them, at time t) and advances the waves over dt.
  virtual void advance(const ParticleView& p, const float* pressure, double t, double dt) = 0;
  virtual std::vector<float> heights(size_t k) const = 0;
  virtual std::vector<float> loads(size_t k) const = 0;  // the last sampled pressure [Pa]
  virtual void set_heights(size_t k, const std::vector<float>& h) = 0;  // and velocities zero
  virtual double last_ms() const = 0;  // device milliseconds of the last advance
  // The render surface of skin k, displaced by its heights along the
  // vertices' normals, in the placed pose (mesh coordinates).
  std::vector<Vec3f> displaced(size_t k) const;

 protected:
  std::vector<SkinGeometry> geo_;
};

std::unique_ptr<SkinSet> make_cpu_skin_set(std::vector<SkinGeometry> geo, const SphParams& prm);
std::unique_ptr<SkinSet> make_cuda_skin_set(std::vector<SkinGeometry> geo, const SphParams& prm);

// The solver itself when there are no skins; else one whose every step also
// advances them (the pressure sampled from the state the step left), on the
// solver's backend. Everything else is the inner solver's. Throws
// std::invalid_argument for PBF (no pressure) and MeshError for a mesh that
// has no skin map.
std::unique_ptr<Solver> with_skins(std::unique_ptr<Solver> inner, const std::vector<SkinInput>& skins,
                                   const SphParams& prm);

}  // namespace sphray
