// The pair stage: one neighbour loop per step computes the acceleration, the
// terms of the density rate and, when asked for, the particle presence and
// the anisotropic field's covariance sums (sph/covariance.h).
//
// Momentum: symmetric pressure gradient with the Tait equation of state,
// Monaghan (1992) artificial viscosity, gravity, and wall forces from boundary
// particles that carry the extrapolated wall pressure p_w of Adami et al.
// (2012; boundary.h) in the same symmetric form, with m_w = rho_w V_w. Walls are
// viscous (the artificial viscosity against a wall at rest, as in DualSPHysics)
// except the faces a scene declares free-slip (per-particle coefficient 0).
// Walls only push: negative pressures are clamped in the wall term, so tension
// cannot glue liquid to a wall.
//
// Density: continuity equation with the delta-SPH density-diffusion term of
// Molteni & Colagrossi (2009, eq. 8) with the hydrostatic correction of
// Fourtakas et al. (2019, "DDT" of DualSPHysics 5): only the departure from the
// hydrostatic density difference diffuses, otherwise the one-sided free surface
// pumps density upward and a tank at rest loses its hydrostatic profile. The
// rate is wanted at the kicked velocities (integrate.h), which exist only after
// this loop. It is linear in the particle's own velocity, so the loop returns
//   drho_i/dt = v'_i . G_i + R_i,
//   G_i = sum_j m_j dW_ij/dr r_ij / r + rho_i sum_b V_b dW_ib/dr r_ib / r,
//   R_i = -sum_j m_j dW_ij/dr (u_j . r_ij) / r + diffusion,
// and Advance completes it with the exact kicked v'_i. For a neighbour the loop
// reads u_j = v_j + dt_prev a_j,prev, its velocity kicked with the previous
// step's acceleration and step size (Advance stores it): a prediction of v'_j
// that is off by dt (a_j - a_j,prev), second order. The artificial viscosity
// reads the same u of both particles (symmetric, so momentum is conserved).
//
// Presence, as defined here: for each signed axis direction d,
//   P_d = min(1, (1 / K) * sum_{j in half-space d} V_i (-dW/dr) |cos(r_ij, d)|)
// with V_i = m / rho_i and K the same sum for a particle inside a full cubic
// lattice of the scene's spacing (setup.cpp, presence_lobe_on_lattice): a
// particle deep in the liquid reads ~1 in all six directions, a free-surface
// particle 0 toward the air (~1 into the liquid, in between sideways) and an
// isolated one 0; the particle itself weighs nothing (r = 0). Per axis a, with
// U_a = sum_j m (dW/dr / r) |r_a| and the fluid part of G above,
// G_a = sum_j m (dW/dr / r) r_a, the two lobes are (G_a - U_a) / (2 K rho_i)
// toward +a (neighbours with r_a < 0 lie toward +a) and -(G_a + U_a) / (2 K rho_i)
// toward -a: presence costs one FMA per axis and neighbour (|r_a| is an
// operand modifier on the GPU). (Yasuda, Harada & Kawaguchi, docs/references.md,
// sec. 4.2.3; their own weight is an ad hoc k / (x / y^2); any smooth lobe
// with these three properties serves the field builder. The particle's own
// volume rather than V_j is what lets G serve: with V_j it cost twice the
// FMAs and, with its six accumulators, spilled registers.) Only liquid
// counts: walls are not liquid.
//
// Why one loop: on the GPU both loops were bound by the scattered 16-byte
// neighbour loads (docs/notebook/benchmarks-history.md), and both loaded the same two per
// neighbour; one loop loads them once.
#pragma once

#include <cmath>
#include <cstdint>

#include "boundary.h"
#include "covariance.h"
#include "mirror_walls.h"
#include "nsearch/pair_masks.h"
#include "presence.h"

namespace sphray {

// The sorted walls as the pair loop reads them.
struct WallsIn {
  const uint32_t* offsets;   // slab table (nsearch/grid.h)
  const Float4* pos_volume;  // x, y, z, volume
  const WallState* state;    // boundary.h, this step's
  const float* alpha;        // artificial viscosity against each wall particle; 0 = free slip
  const Float4* velocity = nullptr;  // each wall particle's velocity (moving obstacles); null: all at rest
};

// What the pair loop writes per fluid particle.
struct PairOut {
  Float4* accel;      // ax, ay, az, R
  Float4* rate_grad;  // G, -
  float* presence;    // [6][n] direction-major (+x,-x,+y,-y,+z,-z); null without presence
  Float4* covariance = nullptr;  // [3][n] (sph/covariance.h); null without it
  float covariance_inv_radius = 0;  // 1 / the sums' radius [1/m]
  // The sums' radius [m] where they take the images across the tank's walls
  // (mirror_walls.h; field.anisotropy.mirror_walls), else 0.
  float covariance_mirror_reach = 0;
};

// What the masked loops fetch of a neighbour (for_each_masked).
struct FluidNeighbour {
  Float4 pos_rho, flow;
};
struct WallNeighbour {
  Float4 pos_volume;
  WallState state;
  float alpha;
};

// What the pair loop computes besides the forces and the density rate:
// nothing, presence, or presence and the anisotropic kernels' covariance
// sums (sph/covariance.h) on the steps that reach an output frame.
enum PairExtras { kPairPlain = 0, kPairPresence = 1, kPairPresenceCovariance = 2 };

// Direct: the launch for the particles whose pair masks overflowed (nsearch/pair_masks.h).
// K: the scene's kernel (prm.kernel.type), fixed at compile time in the loop.
template <int Extras, bool Direct, KernelType K>
struct Interaction {
  static constexpr bool WithPresence = Extras != kPairPlain;
  static constexpr bool WithCovariance = Extras == kPairPresenceCovariance;
  // The loop's constants, computed once on the host: they reach the GPU as
  // kernel parameters and cost the loop no registers (computed per thread,
  // the three of hydro_g spilled the cubic spline's loop).
  struct Constants {
    float eta2;            // Monaghan's eta^2 = 0.01 h^2 keeps mu finite for close pairs
    // mu / rho_mean = h vr / ((r^2 + eta^2) (rho_i + rho_j) / 2), written as
    // 2h vr / ((r^2 + eta^2) (rho_i + rho_j)): one multiplication fewer.
    float two_h;
    // The diffusion coefficient 2 delta h c0 times the particle mass, for
    // the weight V_j (-dW/dr / r) = m (-dW/dr / r) / rho_j.
    float diffusion_mass;
    // Linearised Tait: hydrostatic rho_j - rho_i = (rho0 / c0^2) g.(x_j - x_i).
    Vec3f hydro_g;
    static Constants of(const SphParams& p) {
      const float h = p.kernel.h;
      return {0.01f * h * h, 2.0f * h, 2.0f * p.density_diffusion * h * p.speed_of_sound * p.particle_mass,
              (p.rest_density / (p.speed_of_sound * p.speed_of_sound)) * p.gravity};
    }
  };

  // Registers per thread on the GPU (core/launch_cuda.cuh): 48 without
  // presence and 56 with it, above the file-wide cap of 40 (CMakeLists.txt),
  // under which both variants spill (presence's three more accumulators; the
  // fetched neighbour structs); measured against 40, 48, 56 and 64 in
  // docs/notebook/benchmarks-history.md.
  // With the covariance's eleven accumulators and the walls' images it
  // takes 64-72: at 64 it spills 12-16 bytes, yet the pair stage with the
  // sums runs 1.5% faster at 1M than at 72 without spills, and the same at
  // 125k (docs/notebook/benchmarks-history.md, "The covariance pair loop at
  // 64 registers"). It runs on the steps that reach an output frame only.
  static constexpr int kMaxRegisters = WithCovariance ? 64 : WithPresence ? 56 : 48;
  SphParams prm;
  GridGeom grid;
  FluidIn fluid;
  WallsIn walls;
  PairMask fluid_pairs, boundary_pairs;  // nsearch/pair_masks.h, built with the grid
  PairOut out;
  uint32_t n;
  Constants c = Constants::of(prm);  // from prm, when the launch is made

  // The six lobes of particle i from the fluid sums (G before the walls add
  // to it, U), s = 1 / (2 K rho_i).
  SPHRAY_HD SPHRAY_FORCEINLINE void write_presence(uint32_t i, float s, Vec3f grad, float ux, float uy,
                                                   float uz) const {
    write_presence_lobes(out.presence, n, i, s, grad, ux, uy, uz);
  }

  SPHRAY_HD void operator()(uint32_t i) const {
    if (masks_complete(fluid_pairs, boundary_pairs, i) == Direct) return;  // the other launch's particle
    const Float4 pi = fluid.pos_rho[i];
    const Vec3f xi = xyz(pi);
    const Float4 flow_i = fluid.flow[i];
    const Vec3f ui = xyz(flow_i);
    const float support2 = prm.kernel.support() * prm.kernel.support();
    const float p_over_rho2_i = flow_i.w;  // pressure_term(rho_i), see params.h
    Vec3f a = {0.0f, 0.0f, 0.0f}, grad = {0.0f, 0.0f, 0.0f};
    float rest = 0.0f;
    // Presence's U_a in registers (named scalars, not an indexed array, so the
    // GPU keeps them out of local memory).
    float ux = 0, uy = 0, uz = 0;
    CovarianceSums cov;
    // The covariance's images across the tank's walls within its radius: i's
    // own first, then each neighbour's after it (as the field's own pass,
    // field/anisotropy.h). An image is no nearer to i than its original, so
    // the neighbours within the support hold every image within the radius.
    const Mirrors mirrors = WithCovariance && out.covariance_mirror_reach > 0.0f
                                ? mirrors_near(prm.tank, prm.open_top, out.covariance_mirror_reach, xi)
                                : Mirrors{};
    auto add_image = [&](Vec3f image, uint32_t) {
      const Vec3f d = (image - xi) * out.covariance_inv_radius;
      cov.add(d.x, d.y, d.z, length2(d));
    };
    if (WithCovariance && mirrors.axes != 0u) mirrors.images(xi, add_image);

    for_each_pair<Direct>(grid, fluid.offsets, fluid.pos_rho, xi, support2, i, fluid_pairs, i,
                          [&](uint32_t j) { return FluidNeighbour{load(fluid.pos_rho + j), load(fluid.flow + j)}; },
                          [&](uint32_t, const FluidNeighbour& d) {
      const Float4 pj = d.pos_rho, fj = d.flow;
      const Vec3f r = xi - xyz(pj);
      const float r2 = length2(r);
      const float dwr = prm.kernel.template dW_over_r_for<K>(r2 * inv_sqrt(r2));
      const float m_dwr = prm.particle_mass * dwr;
      float term = p_over_rho2_i + fj.w;
      // (u_i - u_j) . r as u_i . r - u_j . r: the second is the continuity
      // term's own, so each pair pays two dot products, not three.
      const float uj_r = dot(xyz(fj), r);
      const float vr = dot(ui, r) - uj_r;
      // Artificial viscosity for approaching pairs: mu / rho_mean with
      // mu = h vr / (r^2 + eta^2), in one division. Computed for every pair
      // and selected: as a branch, a warp ran it whenever any lane's pair
      // approached, and paid the branch besides. The select sits inside the
      // product, so that the subtraction still fuses with it (the results are
      // those of the branch, bit for bit).
      const float visc = fast_div(c.two_h * vr, (r2 + c.eta2) * (pi.w + pj.w));
      term -= prm.viscosity_alpha * prm.speed_of_sound * (vr < 0.0f ? visc : 0.0f);
      a -= (m_dwr * term) * r;
      grad += m_dwr * r;
      const float weight = -dwr * fast_div(c.diffusion_mass, pj.w);  // diffusion V_j (-dW/dr / r) >= 0
      rest += ((pj.w - pi.w) + dot(c.hydro_g, r)) * weight - m_dwr * uj_r;
      if (WithPresence) {
        ux += m_dwr * std::fabs(r.x);
        uy += m_dwr * std::fabs(r.y);
        uz += m_dwr * std::fabs(r.z);
      }
      if (WithCovariance) {  // offsets x_j - x_i in units of the radius
        const float ir = -out.covariance_inv_radius;
        const float q2 = r2 * (ir * ir);
        cov.add(ir * r.x, ir * r.y, ir * r.z, q2);
        // A neighbour beyond the radius has its images beyond it too.
        if (mirrors.axes != 0u && q2 < 1.0f) mirrors.images(xyz(pj), add_image);
      }
    });
    if (WithPresence) write_presence(i, prm.presence_scale / pi.w, grad, ux, uy, uz);  // fluid sums only
    if (WithCovariance) cov.store(out.covariance, n, i);

    // Walls (boundary particles of volume V_b): the wall pressure and
    // viscosity push; approaching a wall compresses the particle (Adami et
    // al. 2012, eq. 22), the rho_i V_b term of G for v_i and, where walls
    // move, -rho_i V_b v_b . grad W in R (without it the walls of a paddle
    // count as at rest and each stroke leaves the liquid denser: the density
    // is floored at rho0 on the way down, not on the way up).
    const float p_wall_i = p_over_rho2_i > 0.0f ? p_over_rho2_i : 0.0f;
    for_each_pair<Direct>(grid, walls.offsets, walls.pos_volume, xi, support2, kNoSkip, boundary_pairs, i,
                          [&](uint32_t b) {
                            return WallNeighbour{load(walls.pos_volume + b), walls.state[b], walls.alpha[b]};
                          },
                          [&](uint32_t b, const WallNeighbour& d) {
      const Float4 pb = d.pos_volume;
      const WallState w = d.state;
      const float alpha = d.alpha;
      const Vec3f r = xi - xyz(pb);
      const float r2 = length2(r);
      const float dwr = prm.kernel.template dW_over_r_for<K>(r2 * inv_sqrt(r2));
      float term = p_wall_i + w.p_over_rho2;
      const float vr = dot(ui, r);
      const float visc = fast_div(c.two_h * vr, (r2 + c.eta2) * (pi.w + w.rho));
      term -= alpha * prm.speed_of_sound * (vr < 0.0f ? visc : 0.0f);  // selected, as for the fluid
      a -= (w.rho * pb.w * term * dwr) * r;
      grad += (pi.w * pb.w * dwr) * r;
      if (walls.velocity) rest -= pi.w * pb.w * dwr * dot(xyz(load(walls.velocity + b)), r);
    });

    a += prm.gravity;
    out.accel[i] = {a.x, a.y, a.z, rest};
    out.rate_grad[i] = {grad.x, grad.y, grad.z, 0.0f};
  }
};

}  // namespace sphray
