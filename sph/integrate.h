// Time integration and the per-step guards. Symplectic Euler, with the density
// treated as the position-like variable it is (continuity density is the time
// derivative of summation density):
//   v' = v + dt a(x, v, rho)             kick
//   rho' = rho + dt drho/dt(x, v')       at x with the kicked v'
//   x' = x + dt v'                       drift
// Evaluating drho/dt with v' (not v) keeps rho consistent with the drift; with
// v it gains energy at every wall bounce (tests/test_sph.cpp, the lone
// particle). a and drho/dt come from one neighbour loop at x (interaction.h):
// the rate is linear in the particle's own velocity, so Advance applies it
// with the exact v'_i, and the neighbours' v'_j are predicted from the previous
// step (u, stored here for the next loop). One force evaluation per step; the
// step is bounded by the CFL, force and viscous limits (Monaghan 1992), so the
// first-order truncation error stays below the spatial error. Particles that
// cross a wall face are put back on it with their outward normal velocity
// removed, and flagged so that the run counts them. Density is floored at the
// rest density (see Advance).
#pragma once

#include <cmath>
#include <cstdint>

#include "obstacles.h"
#include "params.h"
#include "particles.h"

namespace sphray {

// kStatusGhost: a copy of another rank's particle in a decomposed run
// (dist/slab_solver.h): its neighbours read it, but the step neither moves it
// nor counts it in the step's extremes (its own sums lack the neighbours
// beyond the halo); it is replaced by a fresh copy before the next step.
// kStatusGone: a particle that left this rank in an exchange, dropped by the
// grid build that follows it (solver_impl.inl).
enum ParticleStatus : uint8_t { kStatusOk = 0, kStatusClamped = 1, kStatusGhost = 2, kStatusGone = 3 };

// flow.w = p / rho^2 from the density (params.h); Advance keeps it current.
// The pressure [Pa] per particle (Solver::device_pressure).
struct TaitPressureOf {
  SphParams prm;
  const Float4* pos_rho;
  float* out;
  SPHRAY_HD void operator()(uint32_t i) const { out[i] = tait_pressure(prm, pos_rho[i].w); }
};

struct PressureTermOf {
  SphParams prm;
  const Float4* pos_rho;
  Float4* flow;
  SPHRAY_HD void operator()(uint32_t i) const { flow[i].w = pressure_term(prm, pos_rho[i].w); }
};

// What the host needs after the pair loop: the extremes for this step's
// size, the first particle holding a non-finite value, and the wall clamps of
// the previous drift. Reduced on the device (transform_reduce_into).
struct StepStats {
  float max_speed2;
  float max_accel2;
  // The first particle with a non-finite value: its sorted index, plus
  // kBadDerived if only what the pair loop computed (acceleration, density
  // rate) is bad, so that a particle whose own state is bad, the cause, comes
  // before the neighbours it spread to. kNoBadParticle when all are finite.
  uint32_t first_bad;
  uint32_t clamped;
  uint32_t fastest;  // sorted index of the fastest particle (the lowest of equals)
};

constexpr uint32_t kBadDerived = 0x80000000u;
constexpr uint32_t kNoBadParticle = 0xffffffffu;

// The reduction's start: no speed, no acceleration, no bad particle, no clamp.
constexpr StepStats kEmptyStepStats{0.0f, 0.0f, kNoBadParticle, 0u, kNoBadParticle};

// Which limit held a step's size (StepLimits::bound; the run summary counts
// them): the CFL, the solver's own limit (WCSPH: the force limit; PBF: the
// density error and depth limits; DFSPH: its explicit viscosity's,
// ChooseFlowStep's dt_force), WCSPH's viscous limit, or run.max_dt.
enum StepBound : uint8_t { kBoundCfl = 0, kBoundSolver = 1, kBoundViscous = 2, kBoundMaxDt = 3 };
constexpr int kStepBounds = 4;

// The last step's size and what bounded it (Solver::last_limits).
struct StepLimits {
  double dt = 0, dt_cfl = 0, dt_force = 0, dt_viscous = 0;
  uint8_t bound = kBoundCfl;  // StepBound: the limit dt took (before a step is shortened or stretched to land on an output time)
  double max_speed = 0, max_accel = 0;
  // The particle that moved at max_speed: its id (initial index) and where it
  // was. fastest_id is kNoBadParticle where it is not known (a run over
  // several ranks, dist/slab_solver.cpp: it may be another rank's).
  uint32_t fastest_id = kNoBadParticle;
  Vec3f fastest_at = {0.0f, 0.0f, 0.0f};
};

// The step-size rule: Monaghan (1992) / Monaghan & Kos (1999), CFL (sound +
// flow speed), force and viscous limits, in double.
struct StepRule {
  double h, speed_of_sound, cfl, max_dt, dt_viscous;
  SPHRAY_HD StepLimits limits(const StepStats& s) const {
    const double inf = HUGE_VAL;
    StepLimits l;
    l.max_speed = std::sqrt(double(s.max_speed2));
    l.max_accel = std::sqrt(double(s.max_accel2));
    l.dt_cfl = h / (speed_of_sound + l.max_speed);
    l.dt_force = l.max_accel > 0 ? std::sqrt(h / l.max_accel) : inf;
    l.dt_viscous = dt_viscous;
    const double bound = l.dt_cfl < l.dt_force ? l.dt_cfl : l.dt_force;
    const double dt = cfl * (bound < l.dt_viscous ? bound : l.dt_viscous);
    l.dt = dt < max_dt ? dt : max_dt;
    l.bound = !(dt < max_dt) ? kBoundMaxDt
              : !(bound < l.dt_viscous) ? kBoundViscous
              : l.dt_cfl < l.dt_force ? kBoundCfl
                                      : kBoundSolver;
    return l;
  }
};

enum StepOutcome : uint32_t { kStepOk = 0, kStepBadParticle = 1, kStepBelowFloor = 2, kStepSupersonic = 3 };

// One step's decision, made on the device so that the kick follows the
// reduction without the host reading the extremes first (a round trip that
// left the GPU idle every step): the host reads it once, when the step's work
// is done, and raises the error then. A bad particle's state is kept as it
// was found, for the message.
struct StepControl {
  StepStats stats;
  StepLimits limits;  // limits.dt: the step taken when outcome is kStepOk
  uint32_t outcome;   // StepOutcome
  uint32_t bad_id;
  Float4 bad_pos, bad_vel, bad_accel;
};

// Fills control->limits and ->outcome from control->stats (one thread):
// refused for a bad particle, a particle faster than the speed of sound, or a
// dt below min_dt, else dt capped at `remaining` (the time left to the
// caller's `until`, >= 0). A weakly compressible fluid holds only well below
// Mach 1 (its density varies as Mach^2): past it the run goes on stably (the
// CFL limit counts the flow speed) but means nothing, as a scene whose c0 is
// far too low shows (tests/test_sph.cpp). The particle that broke the rule
// is kept for the message.
struct ChooseStep {
  StepRule rule;
  double min_dt, remaining;
  StepControl* control;
  ConstParticleArrays state;  // pos, vel, id: the bad particle's, for the message
  PairIn pairs;
  SPHRAY_HD void operator()(uint32_t) const {
    StepControl& c = *control;
    c.limits = rule.limits(c.stats);
    if (c.stats.fastest != kNoBadParticle) {
      c.limits.fastest_id = state.id[c.stats.fastest];
      c.limits.fastest_at = xyz(state.pos[c.stats.fastest]);
    }
    const bool bad = c.stats.first_bad != kNoBadParticle;
    if (bad || c.limits.max_speed > rule.speed_of_sound) {
      const uint32_t i = bad ? c.stats.first_bad & ~kBadDerived : c.stats.fastest;
      c.outcome = bad ? kStepBadParticle : kStepSupersonic;
      c.bad_id = state.id[i];
      c.bad_pos = state.pos[i];
      c.bad_vel = state.vel[i];
      c.bad_accel = pairs.accel[i];
      return;
    }
    if (c.limits.dt < min_dt) {
      c.outcome = kStepBelowFloor;  // limits.dt: the step refused
      return;
    }
    c.outcome = kStepOk;
    c.limits.dt = c.limits.dt < remaining ? c.limits.dt : remaining;
  }
};

// Kick, density, drift, and what the next pair loop reads of the particle.
// The step's size comes from the device (ChooseStep, above); a step that
// ChooseStep refused (a bad particle, dt below its floor) leaves every
// particle as it is.
struct Advance {
  SphParams prm;
  const StepControl* control;
  // pos: x, density; vel: the exact velocity (w unused); out: flow, u = v' +
  // dt a (the next loop's prediction of v''), p / rho'^2; status
  ParticleArrays state;
  PairIn pairs;  // a, R and G (interaction.h)
  Obstacles obstacles;  // the path of each particle is stopped at them (obstacles.h)

  SPHRAY_HD static void keep_inside(float& x, float& v, float lo, float hi, bool clamp_hi, uint8_t& st) {
    if (x < lo) { x = lo; if (v < 0.0f) v = 0.0f; st = kStatusClamped; }
    if (clamp_hi && x > hi) { x = hi; if (v > 0.0f) v = 0.0f; st = kStatusClamped; }
  }

  SPHRAY_HD void operator()(uint32_t i) const {
    if (control->outcome != kStepOk || state.status[i] == kStatusGhost) return;
    const float dt = float(control->limits.dt);
    Float4 p = state.pos[i];
    Float4 v = state.vel[i];
    const Float4 a = pairs.accel[i], g = pairs.rate_grad[i];
    v.x += dt * a.x; v.y += dt * a.y; v.z += dt * a.z;
    const float rate = v.x * g.x + v.y * g.y + v.z * g.z + a.w;
    p.x += dt * v.x; p.y += dt * v.y; p.z += dt * v.z;
    // No tension: a free-surface liquid cannot pull, and a particle flying off
    // the bulk would otherwise decompress (continuity density drops by the
    // sum it leaves behind) into a strongly attractive, even negative, density.
    // Flooring at rest density keeps p >= 0 (as the clamped free-surface
    // WCSPH of Becker & Teschner 2007 does).
    const float rho = p.w + dt * rate;
    p.w = rho > prm.rest_density ? rho : prm.rest_density;
    uint8_t st = kStatusOk;
    keep_inside(p.x, v.x, prm.tank.min.x, prm.tank.max.x, true, st);
    keep_inside(p.y, v.y, prm.tank.min.y, prm.tank.max.y, true, st);
    keep_inside(p.z, v.z, prm.tank.min.z, prm.tank.max.z, !prm.open_top, st);
    Vec3f u = {v.x + dt * a.x, v.y + dt * a.y, v.z + dt * a.z};
    if (obstacles.count > 0) {
      Vec3f x = xyz(p);
      const Stop stop = stop_at_obstacles(obstacles, xyz(state.pos[i]), x, obstacles.time, obstacles.time + dt);
      if (stop.hit()) {
        const Vec3f w = velocity_after(xyz(v), stop);
        v.x = w.x; v.y = w.y; v.z = w.z;
        u = velocity_after(u, stop);
        x = inside_tank(prm, x);
        p.x = x.x; p.y = x.y; p.z = x.z;
        st = kStatusClamped;
      }
    }
    state.pos[i] = p;
    state.vel[i] = v;
    state.flow[i] = {u.x, u.y, u.z, pressure_term(prm, p.w)};
    state.status[i] = st;
  }
};

struct StepStatsOf {
  ConstParticleArrays state;
  PairIn pairs;

  SPHRAY_HD StepStats operator()(uint32_t i) const {
    if (state.status[i] == kStatusGhost) return kEmptyStepStats;
    const Float4 p = state.pos[i], v = state.vel[i], a = pairs.accel[i];
    const bool finite = all_finite(xyz(p)) && std::isfinite(p.w) && all_finite(xyz(v)) && p.w > 0.0f;
    const bool derived = all_finite(xyz(a)) && std::isfinite(a.w);
    const uint32_t bad = !finite ? i : !derived ? i | kBadDerived : kNoBadParticle;
    return {length2(xyz(v)), length2(xyz(a)), bad, state.status[i] == kStatusClamped ? 1u : 0u, i};
  }
};

struct CombineStepStats {
  SPHRAY_HD StepStats operator()(const StepStats& a, const StepStats& b) const {
    const bool a_faster = a.max_speed2 > b.max_speed2 || (a.max_speed2 == b.max_speed2 && a.fastest < b.fastest);
    return {a_faster ? a.max_speed2 : b.max_speed2, a.max_accel2 > b.max_accel2 ? a.max_accel2 : b.max_accel2,
            a.first_bad < b.first_bad ? a.first_bad : b.first_bad, a.clamped + b.clamped,
            a_faster ? a.fastest : b.fastest};
  }
};

}  // namespace sphray
