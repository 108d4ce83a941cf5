// Divergence-free SPH (Bender & Koschier, "Divergence-Free Smoothed Particle
// Hydrodynamics", SCA 2015, and "Divergence-Free SPH for Incompressible and
// Viscous Fluids", TVCG 2017): the per-particle stages of one step, written
// once for both backends. With V = m / rho0 and d_i = rho_i / rho0:
//   forces    v* = v + dt (g + viscosity)                          (DfsphViscosity)
//   pressure  solve A p = 1 - d* for p >= 0, where d*_i = d_i + dt sum_j V (v*_i - v*_j).grad W_ij
//             is the density the velocities lead to, and A p the density change
//             dt^2 sum_j V (a_i - a_j).grad W_ij of the pressure accelerations
//             a_i = -sum_j V (p_i + p_j) grad W_ij                 (DfsphAccel, DfsphUpdate)
//             then v = v* + dt a, x = x + dt v                      (DfsphKick)
//   grid      sort by x, pair masks, reused by every pass until the next step's advection
//   density   d_i, the DFSPH factor 1 / (|sum_j V grad W_ij|^2 + sum_j |V grad W_ij|^2),
//             the density rate, presence                           (DfsphDensity)
//   divergence  the same system with the density change over dt of the
//             velocities, -dt Dd/Dt, as its right side: the velocity field
//             made divergence-free, so that the next step starts without
//             the compression it would otherwise carry            (DfsphUpdate<true>)
// Both solves are relaxed Jacobi iterations on the pressure itself, as in
// SPlisHSPlasH's DFSPH (Bender et al., from 2020): p_i <- max(p_i + w r_i
// factor_i / dt^2, 0) with the residual r_i = (A p)_i - s_i (w = 0.5, less for
// wide supports: DfsphParams::jacobi_weight), until the mean
// residual (compression only) is below the tolerance, with at least
// dfsph.min_iterations pressure iterations and one divergence iteration.
// Each starts from half the pressure it ended with the step before (warm
// start; kept as p dt^2 so that it does not depend on the step size).
// Walls: the tank's planes as mirrors (mirror_walls.h): the images of a
// particle and of its neighbours within the support, of volume V, add to
// the density, the factor, the density rate and the pressure force.
// The images carry their originals' pressure and mirrored velocity and
// acceleration (ghost particles: the liquid continued symmetrically across
// the wall, Colagrossi & Landrini 2003), so that the solve's model of the
// density change is the one the next density pass measures: as static
// particles (no velocity, the particle's own pressure only) the images
// under-predicted the compression at the floor and in the corners, and a
// column at rest blew up within 0.2 s.
// The obstacles' wall particles (mesh_walls.h) are static: they add to the
// density, to the factor's gradient sum (not to its sum of squares: they do
// not move) and to the density rate with their own velocity, and push with
// the pressure of Adami et al. (2012) for a wall particle, the particle's own
// continued hydrostatically and not below zero,
//   a_i -= sum_b V_b (p_i + p_b) grad W_ib,  p_b = p_i + max(g . (x_b - x_i), -p_i),
// the part 2 p_i in the solve (as the tank's mirror images carry p_i), the
// hydrostatic part, with p_i in its bound from the step before, as an
// explicit force with gravity. Mirrored pressure alone (p_b = p_i, Akinci et
// al. 2012) read 1% high over a submerged box and 3% low under it, the
// buoyancy 5% low; the weight 1 of SPlisHSPlasH's DFSPH (p_i alone) held the
// liquid with twice the pressure at the wall. Their sums depend on the
// positions only, so the density pass computes them once per grid
// (WallSum) and the solves read them.
// Viscosity is explicit (Monaghan 2005, the form SPlisHSPlasH's "Standard"
// viscosity uses):
//   a_i = 2 (d + 2) nu sum_j V (v_ij . x_ij) / (|x_ij|^2 + 0.01 h^2) grad W_ij,
// with the images' velocities making each wall free-slip or no-slip.
#pragma once

#include <cmath>
#include <cstdint>

#include "dfsph_params.h"
#include "flow_step.h"
#include "mesh_walls.h"
#include "mirror_walls.h"
#include "obstacles.h"
#include "params.h"
#include "presence.h"

namespace sphray {

// V grad W at r, |r|^2 = r2: a neighbour's term in every sum below.
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f volume_grad(const DfsphParams& df, Vec3f r, float r2) {
  return (df.volume * df.kernel.dW_over_r_sq(r2)) * r;
}

// What the obstacles' wall particles add to a particle's sums at the
// positions of the grid, as the forces and the solves read them: sum_b V_b
// grad W_ib, the hydrostatic push and sum_b V_b v_b . grad W_ib (moving
// walls). Written by the density pass, which also adds their share of the
// density and their count itself.
struct WallSum {
  Vec3f grad;
  Vec3f push;  // sum_b V_b max(g . (x_b - x_i), -p_i) grad W_ib: the walls' hydrostatic part
  float rate;
};

// The density, the DFSPH factor, the density rate of the divergence solve and,
// when asked for, presence, at the current positions (sorted, masks built).
//   pos_out[i] = {x_i, rho_i}; factor[i]; source[i] = max(Dd_i/Dt, 0), 0 where
//   sparse; sparse[i]; error[i] = max(d_i - 1, 0) (the state's compression).
template <bool WithPresence, int P>
struct DfsphDensity {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  SphParams prm;
  DfsphParams df;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const Float4* pos;
  const Float4* vel;
  Float4* pos_out;
  float* factor;
  float* source;
  uint8_t* sparse;
  float* error;
  float* presence;  // [6][n]; null without presence
  uint32_t n;
  WallsView walls;
  WallSum* wall_sum;  // out where the obstacles' walls are near
  const Float4* warm;  // the pressure solve's p dt^2 (DfsphKick): the bound of the walls' hydrostatic part
  const FlowControl* control;  // the step's dt; null before the first step (the bound is then 0)
  SPHRAY_HD void operator()(uint32_t i) const {
    const SmoothingKernel<float>& k = df.kernel;
    const float s2 = k.support() * k.support();
    const Vec3f xi = xyz(pos[i]), vi = xyz(vel[i]);
    const Mirrors mirrors = mirrors_of(prm, k.support(), xi);
    const bool near_mesh = walls.near_point(xi);
    float w_sum = k.W(0.0f), g2 = 0.0f, rate = 0.0f;
    Vec3f grad = {0.0f, 0.0f, 0.0f};
    PresenceSums lobes;
    uint32_t count = 0;
    // Images move with their originals' mirrored velocity.
    auto velocity = [&](uint32_t j, Float4) { return xyz(load(vel + j)); };
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pos, i, xi, s2, mirrors, vi, velocity,
                                    [&](Vec3f r, float r2, Vec3f vj, uint32_t set) {
      w_sum += k.W(fast_sqrt(r2));
      const float vdw = df.volume * k.dW_over_r_sq(r2);
      const Vec3f g = vdw * r;
      grad += g;
      g2 += length2(g);
      rate += dot(vi - Mirrors::flip(vj, set), g);
      ++count;
      if (WithPresence && set == 0u) lobes.add(vdw, r);  // the liquid itself, not its images
    });
    float d = df.volume * w_sum;
    Vec3f wall_grad = {0.0f, 0.0f, 0.0f};
    if (with_mesh_walls(P) && near_mesh) {
      WallSum ws{{0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, 0.0f};
      float wall_volume = 0.0f;
      const float dt = control ? float(control->limits.dt) : 0.0f;
      const float p_last = dt > 0.0f ? warm[i].x / (dt * dt) : 0.0f;
      walls.for_each_near(xi, k.support(), [&](uint32_t b, Float4 pb, Vec3f r, float r2) {
        wall_volume += pb.w * k.W(fast_sqrt(r2));
        const Vec3f g = (pb.w * k.dW_over_r_sq(r2)) * r;
        ws.grad += g;
        ws.push += fmaxf(-dot(prm.gravity, r), -p_last) * g;  // r = x_i - x_b
        if (walls.vel) ws.rate += dot(xyz(load(walls.vel + b)), g);
        ++count;
      });
      wall_sum[i] = ws;
      d += wall_volume;
      rate += dot(vi, ws.grad) - ws.rate;
      wall_grad = ws.grad;
    }
    if (WithPresence) lobes.write(presence, n, i, df.presence_scale);  // rest volume: presence.h
    // p_i's own coefficient in (A p)_i: its acceleration -p_i (grad + 2 G_w) against the density's gradient grad + G_w.
    const float denom = dot(grad + 2.0f * wall_grad, grad + wall_grad) + g2;
    const bool thin = float(count) < df.sparse_neighbours;
    pos_out[i] = {xi.x, xi.y, xi.z, prm.rest_density * d};
    factor[i] = denom > 0.0f ? 1.0f / denom : 0.0f;
    source[i] = thin ? 0.0f : fmaxf(rate, 0.0f);
    sparse[i] = thin ? 1 : 0;
    error[i] = fmaxf(d - 1.0f, 0.0f);
  }
};

// The pressure accelerations a_i = -sum_j V (p_i + p_j) grad W_ij (the
// images with their originals' pressure) into acc[i]. WithSource (the first pressure iteration): also the density
// the velocities lead to, d*_i = d_i + dt Dd_i/Dt, into source[i].
template <bool WithSource, int P>
struct DfsphAccel {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  SphParams prm;
  DfsphParams df;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const FlowControl* control;
  const Float4* pos;
  const Float4* vel;
  const float* press;
  Float4* acc;
  float* source;
  WallsView walls;
  const WallSum* wall_sum;
  SPHRAY_HD void operator()(uint32_t i) const {
    const SmoothingKernel<float>& k = df.kernel;
    const float s2 = k.support() * k.support();
    const Float4 pi4 = pos[i];
    const Vec3f xi = xyz(pi4);
    const Mirrors mirrors = mirrors_of(prm, k.support(), xi);
    const bool near_mesh = walls.near_point(xi);
    const float pi = press[i];
    const Vec3f vi = WithSource ? xyz(vel[i]) : Vec3f{0.0f, 0.0f, 0.0f};
    Vec3f a = {0.0f, 0.0f, 0.0f};
    float rate = 0.0f;
    // Each neighbour's pressure and, WithSource, velocity (an image's: its original's, mirrored).
    struct State {
      float p;
      Vec3f v;
    };
    auto state = [&](uint32_t j, Float4) {
      return State{press[j], WithSource ? xyz(load(vel + j)) : Vec3f{0.0f, 0.0f, 0.0f}};
    };
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pos, i, xi, s2, mirrors, State{pi, vi}, state,
                                    [&](Vec3f r, float r2, const State& o, uint32_t set) {
      const Vec3f g = volume_grad(df, r, r2);
      a -= (pi + o.p) * g;
      if (WithSource) rate += dot(vi - Mirrors::flip(o.v, set), g);
    });
    if (with_mesh_walls(P) && near_mesh) {
      const WallSum ws = wall_sum[i];
      a -= (2.0f * pi) * ws.grad;
      if (WithSource) rate += dot(vi, ws.grad) - ws.rate;
    }
    acc[i] = {a.x, a.y, a.z, 0.0f};
    if (WithSource) source[i] = pi4.w / prm.rest_density + float(control->limits.dt) * rate;
  }
};

// One relaxed Jacobi iteration of either solve: with (A p)_i = dt^2 sum_j V
// (a_i - a_j).grad W_ij (the images with their originals' mirrored a) and s_i = 1 - d*_i (pressure) or -dt Dd_i/Dt
// (divergence), r_i = (A p)_i - s_i; p_i <- max(p_i + w r_i factor_i / dt^2, 0)
// (w: DfsphParams::jacobi_weight);
// residual[i] = max(-(s_i - (A p)_i), 0) = max(r_i, 0): the compression left
// (0 at a sparse particle in the divergence solve).
template <bool Divergence, int P>
struct DfsphUpdate {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  SphParams prm;
  DfsphParams df;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const FlowControl* control;
  const Float4* pos;
  const Float4* acc;
  const float* factor;
  const float* source;
  const uint8_t* sparse;
  float* press;
  float* residual;
  WallsView walls;
  const WallSum* wall_sum;
  SPHRAY_HD void operator()(uint32_t i) const {
    const SmoothingKernel<float>& k = df.kernel;
    const float s2 = k.support() * k.support();
    const Vec3f xi = xyz(pos[i]);
    const Mirrors mirrors = mirrors_of(prm, k.support(), xi);
    const bool near_mesh = walls.near_point(xi);
    const Vec3f ai = xyz(acc[i]);
    float ap = 0.0f;
    auto accel = [&](uint32_t j, Float4) { return xyz(load(acc + j)); };
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pos, i, xi, s2, mirrors, ai, accel,
                                    [&](Vec3f r, float r2, Vec3f aj, uint32_t set) {
      ap += dot(ai - Mirrors::flip(aj, set), volume_grad(df, r, r2));
    });
    if (with_mesh_walls(P) && near_mesh) ap += dot(ai, wall_sum[i].grad);  // the walls do not accelerate
    const float dt = float(control->limits.dt), dt2 = dt * dt;
    const float s = Divergence ? -dt * source[i] : 1.0f - source[i];
    const float r = dt2 * ap - s;
    press[i] = fmaxf(press[i] + df.jacobi_weight * r * factor[i] / dt2, 0.0f);
    residual[i] = Divergence && sparse[i] ? 0.0f : fmaxf(r, 0.0f);
  }
};

// The explicit forces: v*_i = v_i + dt (g + 2 (d + 2) nu sum_j V (v_ij . x_ij) /
// (|x_ij|^2 + 0.01 h^2) grad W_ij - WallSum::push), into vel_out. The wall images take part
// with the velocity that makes their wall free-slip or no-slip as the scene
// says (Mirrors::viscous_image; tank.free_slip).
template <int P>
struct DfsphViscosity {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  SphParams prm;
  DfsphParams df;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const FlowControl* control;
  const Float4* pos;
  const Float4* vel;
  Float4* vel_out;
  WallsView walls;
  const WallSum* wall_sum;
  SPHRAY_HD void operator()(uint32_t i) const {
    const SmoothingKernel<float>& k = df.kernel;
    const float s2 = k.support() * k.support();
    const Vec3f xi = xyz(pos[i]), vi = xyz(vel[i]);
    const Mirrors mirrors = mirrors_of(prm, k.support(), xi);
    Vec3f lap = {0.0f, 0.0f, 0.0f};
    auto velocity = [&](uint32_t j, Float4) { return xyz(load(vel + j)); };
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pos, i, xi, s2, mirrors, vi, velocity,
                                    [&](Vec3f r, float r2, Vec3f vj, uint32_t set) {
      const Vec3f vij = vi - mirrors.viscous_image(vj, set, df.no_slip_faces);
      lap += (dot(vij, r) / (r2 + df.viscosity_eta2)) * volume_grad(df, r, r2);
    });
    const float dt = float(control->limits.dt);
    Vec3f a = prm.gravity + df.viscosity * lap;
    if (walls.near_point(xi)) a -= wall_sum[i].push;
    const Vec3f v = vi + dt * a;
    vel_out[i] = {v.x, v.y, v.z, 0.0f};
  }
};

// v* = v + dt g where there is no viscosity pass (with the walls' hydrostatic part).
struct DfsphGravity {
  SphParams prm;
  const FlowControl* control;
  const Float4* pos;
  Float4* vel;
  WallsView walls;
  const WallSum* wall_sum;
  SPHRAY_HD void operator()(uint32_t i) const {
    Vec3f a = prm.gravity;
    if (walls.near_point(xyz(pos[i]))) a -= wall_sum[i].push;
    const Vec3f v = xyz(vel[i]) + float(control->limits.dt) * a;
    vel[i] = {v.x, v.y, v.z, 0.0f};
  }
};

// The warm start of a solve: half the pressure the same solve ended with at
// the step before (kept as p dt^2 in warm[i]: x the pressure solve's, y the
// divergence solve's). The divergence solve starts from zero where the
// velocities do not compress (source 0), as SPlisHSPlasH does.
// The pressure [Pa] of the last step: p = rho0 d^2 p~ / dt^2, p~ the
// pressure and the divergence solves' variables (kept as p dt^2 in `warm`)
// summed, both pushing over the step (Solver::device_pressure).
struct DfsphPressureOf {
  float rest_density;
  float inv_dt2;
  const Float4* pos;   // w: density
  const Float4* warm;  // x, y: the two solves' p~ dt^2 [m^2]
  float* out;
  SPHRAY_HD void operator()(uint32_t i) const {
    const float d = pos[i].w / rest_density;
    out[i] = rest_density * d * d * (warm[i].x + warm[i].y) * inv_dt2;
  }
};

template <bool Divergence>
struct DfsphWarmStart {
  const FlowControl* control;
  const Float4* warm;
  const float* source;  // the divergence solve's density rate
  float* press;
  SPHRAY_HD void operator()(uint32_t i) const {
    const float dt = float(control->limits.dt);
    if (Divergence) press[i] = source[i] > 0.0f ? 0.5f * warm[i].y / (dt * dt) : 0.0f;
    else press[i] = 0.5f * warm[i].x / (dt * dt);
  }
};

// The end of a solve: v += dt a; the pressure kept for the next warm start
// (p dt^2, DfsphWarmStart); after the pressure solve (Advect) also the
// advection x += dt v, into pos_out and projected into the tank.
template <bool Advect>
struct DfsphKick {
  SphParams prm;
  const FlowControl* control;
  const Float4* acc;
  const float* press;
  Float4* vel;
  Float4* warm;
  const Float4* pos;
  Float4* pos_out;
  Obstacles obstacles;  // the advection is stopped at them (obstacles.h)
  WallsView walls;  // the obstacles' wall particles
  float margin;     // dfsph.wall_margin [m]
  SPHRAY_HD void operator()(uint32_t i) const {
    const float dt = float(control->limits.dt);
    Vec3f v = xyz(vel[i]) + dt * xyz(acc[i]);
    Vec3f x{0.0f, 0.0f, 0.0f};
    if (Advect) {
      // Beside an obstacle's wall particles, a particle the projection holds
      // at a tank face it already lay on loses its velocity into it: in a
      // corner between the floor and a mesh thinner than the support the
      // liquid is not dense enough to push back, and the velocity grew by
      // g dt a step. Elsewhere the mirror images turn it (zeroed there too,
      // the Martin & Moyce front at a/20 erred by 6.0% instead of 4.9%).
      const Vec3f x0 = xyz(pos[i]), want = x0 + dt * v;
      x = inside_tank(prm, want, margin);
      if (walls.near_point(x0)) {
        if (x.x != want.x && x.x == x0.x) v.x = 0.0f;
        if (x.y != want.y && x.y == x0.y) v.y = 0.0f;
        if (x.z != want.z && x.z == x0.z) v.z = 0.0f;
      }
      const Stop stop = stop_at_obstacles(obstacles, xyz(pos[i]), x, obstacles.time, obstacles.time + dt);
      if (stop.hit()) x = inside_tank(prm, x, margin);
      v = velocity_after(v, stop);
    }
    vel[i] = {v.x, v.y, v.z, 0.0f};
    if (Advect) warm[i].x = press[i] * dt * dt;
    else warm[i].y = press[i] * dt * dt;
    if (Advect) pos_out[i] = {x.x, x.y, x.z, pos[i].w};
  }
};

}  // namespace sphray
