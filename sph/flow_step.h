// The step size and state statistics of the incompressible solvers (PBF,
// pbf.h; DFSPH, dfsph.h), whose steps follow the flow rather than the sound
// speed: the largest speed, the density error and the first non-finite
// particle, reduced on the device; the step chosen there from them.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/vec.h"
#include "integrate.h"  // StepLimits, kNoBadParticle, StepOutcome

namespace sphray {

// What the step size and the run's guards read of the state: the largest
// speed, the density error, the first non-finite particle. Reduced on the device.
struct FlowStats {
  float max_speed2;
  float error_max;   // largest compression rho / rho0 - 1 (>= 0)
  double error_sum;  // summed over the particles
  double count;      // the particles summed (a decomposed run's over all ranks: solvers reduce the pairs together)
  uint32_t first_bad;
  uint32_t fastest_id;  // the fastest particle (the lowest id of equals) and where it is
  Vec3f fastest_at;
};
constexpr FlowStats kEmptyFlowStats{0.0f, 0.0f, 0.0, 0.0, kNoBadParticle, kNoBadParticle, {0.0f, 0.0f, 0.0f}};

struct CombineFlowStats {
  SPHRAY_HD FlowStats operator()(const FlowStats& a, const FlowStats& b) const {
    const bool a_faster = a.max_speed2 > b.max_speed2 || (a.max_speed2 == b.max_speed2 && a.fastest_id < b.fastest_id);
    return {a_faster ? a.max_speed2 : b.max_speed2, a.error_max > b.error_max ? a.error_max : b.error_max,
            a.error_sum + b.error_sum, a.count + b.count, a.first_bad < b.first_bad ? a.first_bad : b.first_bad,
            a_faster ? a.fastest_id : b.fastest_id, a_faster ? a.fastest_at : b.fastest_at};
  }
};

// Per particle: speed, density error (from error[]), finiteness; another
// rank's ghosts (status, where given: kStatusGhost) count for nothing.
struct FlowStatsOf {
  const Float4* pos;  // x, density
  const Float4* vel;
  const float* error;
  const uint8_t* status = nullptr;
  const uint32_t* id = nullptr;  // null: the index stands for the id
  SPHRAY_HD FlowStats operator()(uint32_t i) const {
    if (status && status[i] == kStatusGhost) return kEmptyFlowStats;
    const Float4 p = pos[i], v = vel[i];
    const bool finite = all_finite(xyz(p)) && std::isfinite(p.w) && all_finite(xyz(v));
    const float e = error[i];
    return {length2(xyz(v)), e, double(e), 1.0, finite && std::isfinite(e) ? kNoBadParticle : i, id ? id[i] : i, xyz(p)};
  }
};

struct FlowControl {
  FlowStats stats;      // of the state the step starts from
  StepLimits limits;   // limits.dt: the step taken when outcome is kStepOk
  uint32_t outcome;    // StepOutcome (integrate.h)
  bool flowing;        // the largest speed is above flow_speed (ChooseFlowStep)
  double dt_chosen;    // the last step before landing on an output time (0 before the first)
  double error_mean;   // the mean compression of the steps so far, smoothed (ChooseFlowStep)
};

// dt = cfl dx / max(v_max, v_floor), capped at max_dt, at max_dt_solver and
// at the time left. The floor is the flow speed the scene can reach
// (sqrt(g H), io/scene.h), so that a liquid at rest or just released does
// not take steps sized by its small speed alone. max_dt_solver is the
// solver's own limit: PBF's depth limit (its reason in pbf.h), DFSPH's
// explicit viscosity's (dfsph.h; DFSPH iterates to a tolerance and needs no
// depth limit). With error_target > 0 (PBF's pbf.step_error) max_dt_solver
// sizes the first step and is the floor after it; the limit then follows the
// compression the steps leave: with e the larger of the last step's mean
// (stats.error_sum / stats.count) and its running mean (weight kKeep on the past), a step of
// dt asks for dt sqrt(error_target / e) (the compression a step leaves grows
// as dt^2, pbf.h), changed by at most the factors kShrink and kGrow per step,
// so that the speeds, position changes over dt, do not jump
// (docs/method.md, "Step size"). While the largest speed is above
// flow_speed (PBF: pbf.flow_speed sqrt(g H)) the target is error_target_flow
// instead: a flowing liquid takes the larger steps, a liquid at or near rest,
// whose compression at a larger target came back as jitter, the smaller.
// Made on the device, like ChooseStep (integrate.h).
struct ChooseFlowStep {
  double cfl_dx, speed_floor, max_dt, max_dt_solver, min_dt, remaining;
  FlowControl* control;
  double error_target;  // mean compression the step is sized to; 0: max_dt_solver throughout
  double error_target_flow = 0;  // the target above flow_speed; 0: error_target throughout
  double flow_speed = HUGE_VAL;  // [m/s]
  SPHRAY_HD void operator()(uint32_t) const {
    FlowControl& c = *control;
    StepLimits& l = c.limits;
    l.max_speed = std::sqrt(double(c.stats.max_speed2));
    c.flowing = l.max_speed > flow_speed;
    l.fastest_id = c.stats.fastest_id;
    l.fastest_at = c.stats.fastest_at;
    const double v = l.max_speed > speed_floor ? l.max_speed : speed_floor;
    l.dt_cfl = v > 0 ? cfl_dx / v : HUGE_VAL;
    l.dt_force = max_dt_solver;
    // The compression the last step left, as a step of dt_chosen would have
    // left it: a step landed on an output time (below) is shorter or longer
    // than the one chosen, and the compression grows as dt^2. Read as it
    // comes, two half steps' quarter of it would grow the step until a single
    // step lands, whose compression then shrinks it again: the steps would
    // alternate in length, and with them PBF's velocities.
    const double taken = l.dt;
    const double landed = c.dt_chosen > 0 && taken > 0 ? c.dt_chosen / taken : 1.0;
    const double e_now = c.stats.count > 0 ? c.stats.error_sum / c.stats.count * landed * landed : 0.0;
    c.error_mean = c.dt_chosen > 0 ? kKeep * c.error_mean + (1.0 - kKeep) * e_now : e_now;
    if (error_target > 0 && c.dt_chosen > 0) {
      const double target = error_target_flow > 0 && c.flowing ? error_target_flow : error_target;
      const double e = e_now > c.error_mean ? e_now : c.error_mean;
      const double f = e > 0 ? std::sqrt(target / e) : kGrow;
      const double grown = c.dt_chosen * (f < kShrink ? kShrink : f > kGrow ? kGrow : f);
      l.dt_force = grown > max_dt_solver ? grown : max_dt_solver;
    }
    l.dt_viscous = HUGE_VAL;
    const double limit = max_dt < l.dt_force ? max_dt : l.dt_force;
    const double dt = l.dt_cfl < limit ? l.dt_cfl : limit;
    l.dt = dt;
    l.bound = l.dt_cfl < limit ? kBoundCfl : max_dt < l.dt_force ? kBoundMaxDt : kBoundSolver;
    if (dt < min_dt) { c.outcome = kStepBelowFloor; return; }
    c.outcome = kStepOk;
    c.dt_chosen = dt;
    // Landing on an output time: the time left in k equal steps, k the
    // count whose step is nearest dt in ratio, so that the landed steps are
    // as often longer than dt as shorter (steps of at most dt would all be
    // shorter: more steps, at a flow CFL below the one asked for). A landed
    // step is at most kLandStretch dt and passes a hard cap (run.max_dt;
    // without an error target also the solver's limit, such as DFSPH's
    // viscous stability limit) by kLandSlack at most. No much shorter step
    // either: PBF's velocities are position changes over dt and DFSPH's
    // pressures scale with 1 / dt^2, so a step much shorter than the one
    // before turns the compression it left into a large speed or pressure.
    // With k steps to go a step lies within sqrt(1 + 1 / k) of dt, or is
    // shorter where a longer one would pass those limits.
    const double hard = error_target > 0 ? max_dt : (max_dt < max_dt_solver ? max_dt : max_dt_solver);
    const double stretched = kLandStretch * dt < hard ? kLandStretch * dt : hard;
    const double longest = stretched > kLandSlack * dt ? stretched : kLandSlack * dt;
    const double n = remaining / dt;
    double k = std::floor(n);
    if (k < 1.0 || n * n > k * (k + 1.0)) k += 1.0;  // nearest in ratio: the geometric mean sqrt(k (k + 1)) divides
    const double fewest = std::ceil(remaining / longest);
    if (k < fewest) k = fewest;
    l.dt = k <= 1.0 ? remaining : k <= kPlanSteps ? remaining / k : dt;
  }
  static constexpr double kShrink = 0.9, kGrow = 1.05, kKeep = 0.9;
  static constexpr double kLandStretch = 1.1;  // a landed step's most beyond dt
  static constexpr double kLandSlack = 1.01;    // beyond a hard cap: round-off in an interval of whole steps
  static constexpr double kPlanSteps = 64;  // more steps to go (or no output time): dt, then within 0.8% of it
};

}  // namespace sphray
