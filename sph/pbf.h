// Position-based fluids (Macklin & Mueller, "Position Based Fluids", 2013):
// the per-particle stages of one step, written once for both backends.
//   predict   v* = v + dt g, x* = x + dt v*            (Predict)
//   grid      sort by x*, pair masks at x*, reused by every pass below
//   iterate   density constraint C_i = max(rho_i / rho0 - 1, 0):
//             lambda_i = -w_k C_i / (sum_k |grad_k C_i|^2 + eps)    (Lambda)
//             (w_k = 1 while the liquid flows; at rest iteration k's
//             weight, so that no constraint mode overshoots: pbf_weights.h)
//             dx_i = (m / rho0) sum_j (lambda_i + lambda_j + s_corr) grad W_ij
//                    + lambda_i grad_i C_i(walls)                     (Correct)
//   finish    v = (x* - x) / dt, XSPH viscosity, x = x*; the density left
//             and presence at the new positions                      (Finish)
//             Without obstacles the last iteration's Correct and Finish
//             are one pass (CorrectFinish), XSPH and the density then at
//             the positions before that correction.
// The constraint is one-sided (only compression is corrected, as in
// SPlisHSPlasH's PBF): a free surface has no neighbours above it and would
// otherwise be pulled together. Walls are the tank's planes, as mirrors: a
// particle within the support of a wall sees the mirror images of itself
// and of its neighbours across it (across two or three walls at an edge or
// a corner). By default (pbf.images "mirrored") they are the liquid
// mirrored across the wall: they add to its density, to grad_i C_i and to
// the denominator's sum over the neighbours' gradients, and each pushes with
// lambda_i plus its original's lambda (its own image with 2 lambda_i), so a
// particle near a free-slip wall is corrected as in the mirrored liquid
// (tests/test_pbf.cpp checks that against an explicitly mirrored run). With
// "static" they are static wall particles pushing with lambda_i alone, as a
// constraint against a static body does in PBD: a particle pressed against a
// wall then met more compression than its correction undid, and the dam
// break's largest speeds, single particles at the walls, were higher
// (docs/validation.md, "Wall images"). Images follow the
// liquid: a wall beside a free surface mirrors the surface (a half-space of
// liquid beyond each wall instead over-counts there and at corners, and
// pushed the liquid up the walls of a pool at rest). The walls are free-slip.
// Each prediction and correction ends with the position projected into the
// tank, pbf.wall_margin inside its walls, so no particle leaves it
// (mirror_walls.h) or lies on a wall, where it would coincide with its own
// image: W(0) added to its density and no gradient to push it off. The
// obstacles' wall particles (mesh_walls.h) are static wall particles in the
// same way: they add to the density and to grad_i C_i and push with
// lambda_i alone; the Lambda pass keeps their gradient sum for the Correct
// pass at the same positions.
// The step (ChooseFlowStep, flow_step.h) has a depth limit besides the CFL:
// each Jacobi iteration carries a correction about one support, so a column
// of depth H under gravity stays compressed by about g H dt^2 / (K s^2) with
// K iterations (the bottom of a column that the iterations cannot hold up
// within a step); max_dt_depth keeps that at pbf.depth_error, 1% by default
// (make_pbf_params). Above it, deep columns compressed by several percent
// and their corrections came back as spurious speeds of metres per second.
// H is the initial depth; after the first step the limit grows from
// max_dt_depth while the mean compression the steps leave stays below
// pbf.step_error (ChooseFlowStep's error-sized step).
#pragma once

#include <cmath>
#include <cstdint>

#include "flow_step.h"
#include "mesh_walls.h"
#include "mirror_walls.h"
#include "obstacles.h"
#include "params.h"
#include "pbf_params.h"
#include "presence.h"

namespace sphray {

// v* = v + dt g and x* = x + dt v* in the tank, into pred (w: 0), and
// where `keys` is given x*'s slab key on `grid`, for the step's sort.
struct Predict {
  SphParams prm;
  const FlowControl* control;
  const Float4* pos;
  const Float4* vel;
  Float4* pred;
  Obstacles obstacles;  // the path is stopped at them (obstacles.h)
  float margin;         // pbf.wall_margin [m]
  GridGeom grid;
  uint32_t* keys;       // or null
  SPHRAY_HD void operator()(uint32_t i) const {
    const float dt = float(control->limits.dt);
    const Vec3f v = xyz(vel[i]) + dt * prm.gravity;
    Vec3f x = inside_tank(prm, xyz(pos[i]) + dt * v, margin);
    if (stop_at_obstacles(obstacles, xyz(pos[i]), x, obstacles.time, obstacles.time + dt).hit()) x = inside_tank(prm, x, margin);
    pred[i] = {x.x, x.y, x.z, 0.0f};
    if (keys) keys[i] = grid.fine_key_of(x);
  }
};

// (m / rho0) grad W of the spiky kernel at r, |r|^2 = r2: a neighbour's
// term in grad C and in the curl.
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f volume_grad(const PbfParams& pbf, Vec3f r, float r2) {
  return (pbf.volume * pbf.kernel.dW_over_r_sq(r2)) * r;
}

// A neighbour's share of the correction, the factor of (m / rho0) grad W_ij:
// lambda_i + lambda_j, less s_corr, for a neighbour and for a mirrored image
// (set != 0, pbf.mirrored_images: the liquid across the wall, lambda_j its
// original's, i's own images lambda_i again), so that s_corr pushes a
// particle beside a wall as in the mirrored liquid; lambda_i alone for a
// static image.
SPHRAY_HD SPHRAY_FORCEINLINE float correction_scale(const PbfParams& pbf, float r2, float lambda_i, float lambda_j,
                                                    uint32_t set) {
  float scale = lambda_i;
  if (set == 0u || pbf.mirrored_images) {
    scale += lambda_j;
    if (pbf.scorr_coef != 0.0f) {  // off by default: the same for every thread, no divergence
      const float q = pbf.kernel.W(r2) * pbf.inv_w_dq;
      float qn = 1.0f;
      for (int e = 0; e < pbf.scorr_n; ++e) qn *= q;
      scale -= pbf.scorr_coef * qn;
    }
  }
  return scale;
}

// x* moved by the correction dx, at most pbf.max_correction per iteration
// (pbf_params.h), and projected into the tank.
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f corrected(const SphParams& prm, const PbfParams& pbf, Vec3f xi, Vec3f dx) {
  const float len2 = length2(dx);
  if (pbf.max_correction > 0.0f && len2 > pbf.max_correction * pbf.max_correction)
    dx = (pbf.max_correction / std::sqrt(len2)) * dx;
  return inside_tank(prm, xi + dx, pbf.wall_margin);
}

// Density at x* and lambda_i: out[i] = {x*_i, lambda_i}; error[i] = C_i.
// The wall images (Mirrors) add to the density and to grad_i C_i, and, as
// mirrored particles (pbf.mirrored_images), to the sum over the neighbours'
// gradients; static ones do not move and add nothing to it.
template <int P>
struct Lambda {
  // 40 registers where the tank's walls are the only walls: 46 unbounded,
  // and 75% of the warps resident instead of 62.5% (the 1M pass 7% faster,
  // no spills; the obstacles' wall loop would spill).
  static constexpr int kMaxRegisters = P == kInterior || P == kNearWalls ? 40 : kMirrorPassRegisters;
  SphParams prm;
  PbfParams pbf;
  GridGeom grid;
  const uint32_t* offsets;  // slab table of the x* sort
  PairMask pairs;
  const Float4* pred;
  Float4* out;
  float* error;
  WallsView walls;
  Float4* wall_grad;  // out where the obstacles' walls are near: sum_b V_b grad W_ib
  const FlowControl* control;  // whether the liquid flows (ChooseFlowStep): at rest lambda takes rest_weight
  float rest_weight;           // this iteration's (PbfParams::rest_weight)
  SPHRAY_HD void operator()(uint32_t i) const {
    const PbfKernel<float>& k = pbf.kernel;
    const float s2 = k.s * k.s;
    const Vec3f xi = xyz(pred[i]);
    const Mirrors mirrors = mirrors_of(prm, k.s, xi);
    const bool near_mesh = walls.near_point(xi);
    // Per neighbour the GPU pass issues an instruction nearly every cycle
    // (docs/notebook/benchmarks-history.md), so its arithmetic is folded:
    // poly6 once after the loop (W_over_poly6), the volume into the
    // gradient's constant, and |g|^2 = gs^2 r2 instead of from g's
    // components, which leaves g itself to one FMA per component.
    const float v_spiky = pbf.volume * k.spiky;
    float cubes = k.W_over_poly6(0.0f), g2 = 0.0f;
    Vec3f grad = {0.0f, 0.0f, 0.0f};
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pred, i, xi, s2, mirrors, 0, [](uint32_t, Float4) { return 0; },
                                    [&](Vec3f r, float r2, int, uint32_t set) {
      cubes += k.W_over_poly6(r2);
      const float gs = k.scaled_dW_over_r_sq(r2, v_spiky);  // (m / rho0) dW/dr / r: grad_j C_i = -gs r
      grad += gs * r;
      if (set == 0u || pbf.mirrored_images) g2 += gs * gs * r2;
    });
    const float w_sum = k.poly6 * cubes;
    float wall_volume = 0.0f;
    if (with_mesh_walls(P) && near_mesh) {
      Vec3f gw = {0.0f, 0.0f, 0.0f};
      walls.for_each_near(xi, k.s, [&](uint32_t, Float4 pb, Vec3f r, float r2) {
        wall_volume += pb.w * k.W(r2);
        gw += (pb.w * k.dW_over_r_sq(r2)) * r;
      });
      grad += gw;
      wall_grad[i] = {gw.x, gw.y, gw.z, 0.0f};
    }
    const float c = fmaxf(pbf.volume * w_sum + wall_volume - 1.0f, 0.0f);  // rho / rho0 - 1
    const float weight = control->flowing ? 1.0f : rest_weight;
    const float lambda = -weight * c / (length2(grad) + g2 + pbf.epsilon);
    out[i] = {xi.x, xi.y, xi.z, lambda};
    error[i] = c;
  }
};

// The position correction, projected into the tank: out[i] = {x*_i + dx_i, 0}.
// A scene with obstacles stops it at them next (StopCorrection).
template <int P>
struct Correct {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  SphParams prm;
  PbfParams pbf;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const Float4* pred;  // x*, lambda
  Float4* out;
  WallsView walls;
  const Float4* wall_grad;  // Lambda's, at these positions
  SPHRAY_HD void operator()(uint32_t i) const {
    const PbfKernel<float>& k = pbf.kernel;
    const float s2 = k.s * k.s;
    const Float4 pi = pred[i];
    const Vec3f xi = xyz(pi);
    const Mirrors mirrors = mirrors_of(prm, k.s, xi);
    const bool near_mesh = walls.near_point(xi);
    Vec3f dx = {0.0f, 0.0f, 0.0f};
    const float v_spiky = pbf.volume * k.spiky;  // folded once (Lambda)
    auto lambda = [](uint32_t, Float4 pj) { return pj.w; };
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pred, i, xi, s2, mirrors, pi.w, lambda,
                                    [&](Vec3f r, float r2, float lambda_j, uint32_t set) {
      const float scale = correction_scale(pbf, r2, pi.w, lambda_j, set);
      dx += (scale * k.scaled_dW_over_r_sq(r2, v_spiky)) * r;
    });
    if (with_mesh_walls(P) && near_mesh) dx += pi.w * xyz(wall_grad[i]);  // lambda_i only: static wall particles
    const Vec3f x = corrected(prm, pbf, xi, dx);
    out[i] = {x.x, x.y, x.z, 0.0f};
  }
};

// The corrections from `from` to `to` stopped at the obstacles (obstacles.h),
// in their pose at the step's end, and projected into the tank again. A
// pass of its own, run only where the scene has obstacles: inside Correct,
// the path test's registers (63 instead of 40) left half the warps a
// neighbour loop could keep resident.
struct StopCorrection {
  SphParams prm;
  Obstacles obstacles;
  const FlowControl* control;  // the step's dt
  const Float4* from;          // x* before the correction
  Float4* to;                  // after it
  float margin;                // pbf.wall_margin [m]
  SPHRAY_HD void operator()(uint32_t i) const {
    const float t_end = obstacles.time + float(control->limits.dt);
    Vec3f x = xyz(to[i]);
    if (!stop_at_obstacles(obstacles, xyz(from[i]), x, t_end, t_end).hit()) return;
    x = inside_tank(prm, x, margin);
    to[i] = {x.x, x.y, x.z, 0.0f};
  }
};

// The end of the step: v = (x* - x) / dt with XSPH viscosity
// (v_i += c sum_j (m / rho0) (v_j - v_i) W_ij; mirrored images take part with
// their originals' velocities reflected), x = x*, and at x* the density
// with the wall images and the obstacles' walls (error[i] = its compression) and, when asked for,
// presence (fluid only).
template <bool WithPresence, int P>
struct Finish {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  SphParams prm;
  PbfParams pbf;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const FlowControl* control;
  const Float4* pred;  // x*
  const Float4* pos;   // x at the step's start
  Float4* pos_out;     // x*, density
  Float4* vel_out;
  float* error;
  float* presence;     // [6][n]; null without presence
  uint32_t n;
  WallsView walls;
  SPHRAY_HD void operator()(uint32_t i) const {
    const PbfKernel<float>& k = pbf.kernel;
    const Vec3f xi = xyz(pred[i]);
    const Mirrors mirrors = mirrors_of(prm, k.s, xi);
    const bool near_mesh = walls.near_point(xi);
    const float inv_dt = float(1.0 / control->limits.dt);
    const Vec3f vi = inv_dt * (xi - xyz(pos[i]));
    float w_sum = k.W(0.0f);
    Vec3f smooth = {0.0f, 0.0f, 0.0f};
    PresenceSums lobes;
    // A neighbour's velocity over the step; the images add to the density only.
    auto velocity = [&](uint32_t j, Float4 pj) { return inv_dt * (xyz(pj) - xyz(load(pos + j))); };
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pred, i, xi, k.s * k.s, mirrors, vi, velocity,
                                    [&](Vec3f r, float r2, Vec3f vj, uint32_t set) {
      const float w = k.W(r2);
      w_sum += w;
      if (set != 0u) {  // a mirrored image moves as its original reflected (free slip); a static one not at all
        if (pbf.mirrored_images) smooth += w * (Mirrors::flip(vj, set) - vi);
        return;
      }
      smooth += w * (vj - vi);
      // V_j = m / rho0: the volume the lobes are normalised with (make_pbf_params)
      if (WithPresence) lobes.add(pbf.volume * k.dW_over_r_sq(r2), r);
    });
    float wall_volume = 0.0f;
    if (with_mesh_walls(P) && near_mesh)
      walls.for_each_near(xi, k.s, [&](uint32_t, Float4 pb, Vec3f, float r2) { wall_volume += pb.w * k.W(r2); });
    const float rho_rel = pbf.volume * w_sum + wall_volume;
    const float rho = prm.rest_density * rho_rel;
    // Weighed by the rest volume, not m / rho_i: the summed density falls by
    // the kernel's deficit at a free surface, and dividing by it would count
    // a flat surface's lateral neighbours as a full lattice (presence.h).
    if (WithPresence) lobes.write(presence, n, i, pbf.presence_scale);
    const Vec3f v = vi + (pbf.xsph * pbf.volume) * smooth;
    pos_out[i] = {xi.x, xi.y, xi.z, rho};
    vel_out[i] = {v.x, v.y, v.z, 0.0f};
    error[i] = fmaxf(rho_rel - 1.0f, 0.0f);
  }
};

// The last iteration's correction and the end of the step in one pass,
// where the scene has no obstacles (whose stop must come between the two):
// x*_i + dx_i as Correct makes it from (x*, lambda) at the last iteration's
// positions, projected into the tank; v = (that - x) / dt with XSPH over the
// neighbours' velocities at those positions, (x*_j - x_j) / dt, before the
// correction; the density (pos_out.w) and presence there too. So a step
// runs 2K neighbour passes for K iterations, not 2K + 1, and error[] keeps
// Lambda's: the compression at the last iteration, before its correction.
// Measured against Correct then Finish: docs/benchmarks.md.
template <bool WithPresence, int P>
struct CorrectFinish {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  SphParams prm;
  PbfParams pbf;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const FlowControl* control;
  const Float4* pred;  // x*, lambda
  const Float4* pos;   // x at the step's start
  Float4* pos_out;     // x* corrected, density
  Float4* vel_out;
  float* presence;     // [6][n]; null without presence
  uint32_t n;
  SPHRAY_HD void operator()(uint32_t i) const {
    const PbfKernel<float>& k = pbf.kernel;
    const Float4 pi = pred[i];
    const Vec3f xi = xyz(pi);
    const Mirrors mirrors = mirrors_of(prm, k.s, xi);
    const float inv_dt = float(1.0 / control->limits.dt);
    const Vec3f x0 = xyz(pos[i]);
    const Vec3f vi = inv_dt * (xi - x0);
    // poly6 applied once after the loop, the volume folded into the
    // gradient's constant (Lambda).
    const float v_spiky = pbf.volume * k.spiky;
    float cubes = k.W_over_poly6(0.0f);
    Vec3f dx = {0.0f, 0.0f, 0.0f}, smooth = {0.0f, 0.0f, 0.0f};
    PresenceSums lobes;
    // A neighbour's velocity and lambda; an image's are its original's (i's own: vi, lambda_i).
    auto fetch = [&](uint32_t j, Float4 pj) {
      const Vec3f v = inv_dt * (xyz(pj) - xyz(load(pos + j)));
      return Float4{v.x, v.y, v.z, pj.w};
    };
    const Float4 self{vi.x, vi.y, vi.z, pi.w};
    for_each_neighbour_and_image<P>(grid, offsets, pairs, pred, i, xi, k.s * k.s, mirrors, self, fetch,
                                    [&](Vec3f r, float r2, Float4 a, uint32_t set) {
      const float w = k.W_over_poly6(r2);
      const float v_dwr = k.scaled_dW_over_r_sq(r2, v_spiky);
      cubes += w;
      if (set != 0u) {
        if (pbf.mirrored_images) smooth += w * (Mirrors::flip(xyz(a), set) - vi);
      } else {
        smooth += w * (xyz(a) - vi);
        if (WithPresence) lobes.add(v_dwr, r);
      }
      dx += (correction_scale(pbf, r2, pi.w, a.w, set) * v_dwr) * r;
    });
    const Vec3f x = corrected(prm, pbf, xi, dx);
    if (WithPresence) lobes.write(presence, n, i, pbf.presence_scale);
    const Vec3f v = inv_dt * (x - x0) + (pbf.xsph * pbf.volume * k.poly6) * smooth;
    pos_out[i] = {x.x, x.y, x.z, prm.rest_density * pbf.volume * k.poly6 * cubes};
    vel_out[i] = {v.x, v.y, v.z, 0.0f};
  }
};

// Vorticity confinement (Macklin & Mueller 2013, after Fedkiw et al. 2001),
// off unless pbf.vorticity > 0: after the finishing pass,
//   omega_i = sum_j (m / rho0) grad_i W_ij x (v_j - v_i)        (Vorticity)
//   eta = sum_j (m / rho0) (|omega_j| - |omega_i|) grad_i W_ij, N = eta / |eta|,
//   v_i += dt eps (N x omega_i)                                  (Confine)
// Fluid neighbours only; the pair masks of the step (positions moved by
// the corrections since, which the kernels weigh as they are).
template <bool Direct>
struct Vorticity {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  PbfParams pbf;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const Float4* pos;
  const Float4* vel;
  Float4* omega;  // omega, |omega|
  SPHRAY_HD void operator()(uint32_t i) const {
    if (mask_complete(pairs, i) == Direct) return;
    const PbfKernel<float>& k = pbf.kernel;
    const Vec3f xi = xyz(pos[i]), vi = xyz(vel[i]);
    Vec3f w = {0.0f, 0.0f, 0.0f};
    for_each_pair<Direct>(grid, offsets, pos, xi, k.s * k.s, i, pairs, i, [&](uint32_t j) { return load(vel + j); },
                          [&](uint32_t j, Float4 vj) {
      const Vec3f r = xi - xyz(load(pos + j));
      w += cross(volume_grad(pbf, r, length2(r)), xyz(vj) - vi);
    });
    omega[i] = {w.x, w.y, w.z, std::sqrt(length2(w))};
  }
};

template <bool Direct>
struct Confine {
  static constexpr int kMaxRegisters = kMirrorPassRegisters;
  PbfParams pbf;
  GridGeom grid;
  const uint32_t* offsets;
  PairMask pairs;
  const FlowControl* control;
  const Float4* pos;
  const Float4* omega;
  Float4* vel;
  SPHRAY_HD void operator()(uint32_t i) const {
    if (mask_complete(pairs, i) == Direct) return;
    const PbfKernel<float>& k = pbf.kernel;
    const Vec3f xi = xyz(pos[i]);
    const Float4 wi = omega[i];
    Vec3f eta = {0.0f, 0.0f, 0.0f};
    for_each_pair<Direct>(grid, offsets, pos, xi, k.s * k.s, i, pairs, i, [&](uint32_t j) { return load(omega + j); },
                          [&](uint32_t j, Float4 wj) {
      const Vec3f r = xi - xyz(load(pos + j));
      eta += ((wj.w - wi.w) * pbf.volume * k.dW_over_r_sq(length2(r))) * r;
    });
    const float len = std::sqrt(length2(eta));
    if (!(len > 0.0f)) return;
    const Vec3f f = pbf.vorticity * cross((1.0f / len) * eta, xyz(wi));
    const Float4 v = vel[i];
    const float dt = float(control->limits.dt);
    vel[i] = {v.x + dt * f.x, v.y + dt * f.y, v.z + dt * f.z, v.w};
  }
};

}  // namespace sphray
