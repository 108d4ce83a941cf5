// The hydrostatic tank of docs/validation.md, shared by the cpu test (1 cm) and
// the gpu convergence test (finer spacings): a 0.12 x 0.12 x 0.2 m column at
// rest, artificial viscosity 0.5 to damp the start within the 1 s run, then
// the pressure field against two references (see the fields below).
#pragma once

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "io/metrics.h"
#include "helpers.h"

namespace sphray::test {

struct Hydrostatic {
  size_t particles = 0;
  std::vector<double> energy;  // kinetic energy every 0.1 s, then at the end
  bool all_inside = true;
  uint64_t clamped = 0;
  size_t interior = 0;     // pressure samples between 20% and 90% depth
  double slope = 0;        // least-squares dp/dz there [Pa/m]
  double rho_g = 0;        // mean density there times g [Pa/m]
  double bottom_p = 0;     // mean pressure of the interior particles within 2 dx of the floor [Pa]
  double bottom_w = 0;     // mean weight of the liquid above them per unit area [Pa]
  double slope_error() const { return -slope / rho_g - 1.0; }
  double bottom_error() const { return bottom_p / bottom_w - 1.0; }
};

// Runs the tank at spacing dx on backend b. Reference 1, the hydrostatic law
// dp/dz = -rho g: the least-squares slope of pressure over height between 20%
// and 90% depth against the mean density times g. Reference 2, the pressure
// near the floor against the weight of the liquid above per unit area (the
// mass above over the cross-section: at rest the same everywhere, and
// independent of where the free surface is). Interior particles only (more
// than one support from the side walls); WCSPH pressure carries acoustic
// noise, so both average 10 snapshots over the last 0.2 s.
// c0 > 0 sets sph.speed_of_sound (default: 10 sqrt(g H), docs/method.md);
// smoothing_ratio > 0 sets sph.smoothing_ratio = h / dx (default 2).
// The run settles for `settle` seconds (kinetic energy sampled 8 times), then
// averages 10 snapshots over 0.2 s.
inline Hydrostatic run_hydrostatic(Backend b, double dx, double c0 = 0, double settle = 0.8,
                                   double smoothing_ratio = 0) {
  std::ostringstream text;
  text << R"({"tank": {"min": [0,0,0], "max": [0.12,0.12,0.3]},
    "fluid": [{"min": [0,0,0], "max": [0.12,0.12,0.2]}],
    "sph": {"spacing": )" << dx << (c0 > 0 ? ", \"speed_of_sound\": " + std::to_string(c0) : std::string())
       << (smoothing_ratio > 0 ? ", \"smoothing_ratio\": " + std::to_string(smoothing_ratio) : std::string())
       << R"(, "viscosity_alpha": 0.5}, "run": {"end_time": )" << settle + 0.4 << "}}";
  const Scene s = parse_scene(text.str(), "hydrostatic.json");
  const SphParams prm = make_params(s);
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
  auto solver = b == Backend::Cuda ? make_cuda_solver(in) : make_cpu_solver(in);
  Hydrostatic r;
  r.particles = solver->num_fluid();
  for (int k = 1; k <= 8; ++k) {
    run_until(*solver, settle / 8 * k);
    r.energy.push_back(kinetic_energy(solver->download(), prm.particle_mass));
  }
  std::vector<HostParticles> snapshots;
  for (int k = 1; k <= 10; ++k) {
    run_until(*solver, settle + 0.02 * k);
    snapshots.push_back(solver->download());
  }
  r.energy.push_back(kinetic_energy(snapshots.back(), prm.particle_mass));
  for (const auto& x : snapshots.back().pos) r.all_inside = r.all_inside && inside(x, s);
  r.all_inside = r.all_inside && snapshots.back().pos.size() == r.particles;
  r.clamped = solver->num_clamped();

  const double H = 0.2, g = 9.81, L = 0.12, margin = 2 * prm.kernel.h + 0.005, area = L * L;
  double sz = 0, sp = 0, szz = 0, szp = 0, srho = 0, bottom_p = 0, bottom_w = 0;
  size_t bottom_n = 0;
  for (const HostParticles& snap : snapshots) {
    std::vector<double> zs;
    for (const auto& x : snap.pos) zs.push_back(x.z);
    std::sort(zs.begin(), zs.end());
    for (size_t i = 0; i < snap.pos.size(); ++i) {
      const Vec3f x = snap.pos[i];
      if (x.x < margin || x.x > L - margin || x.y < margin || x.y > L - margin) continue;
      const double depth = H - x.z, p = tait_pressure(prm, snap.density[i]);
      if (depth >= 0.2 * H && depth <= 0.9 * H) {
        sz += x.z; sp += p; szz += double(x.z) * x.z; szp += x.z * p; srho += snap.density[i];
        ++r.interior;
      }
      if (x.z < 2 * dx) {
        bottom_p += p;
        ++bottom_n;
        // Weight above: each particle smeared over one spacing in height
        // (those above z + dx/2 count whole, those within dx/2 in part).
        double above = double(zs.end() - std::upper_bound(zs.begin(), zs.end(), x.z + 0.5 * dx));
        for (auto it = std::lower_bound(zs.begin(), zs.end(), x.z - 0.5 * dx); it != zs.end() && *it <= x.z + 0.5 * dx; ++it)
          above += std::clamp((*it - x.z) / dx + 0.5, 0.0, 1.0);
        bottom_w += g * prm.particle_mass * above / area;
      }
    }
  }
  const double n = double(r.interior);
  r.slope = (n * szp - sz * sp) / (n * szz - sz * sz);
  r.rho_g = srho / n * g;
  r.bottom_p = bottom_p / double(bottom_n);
  r.bottom_w = bottom_w / double(bottom_n);
  return r;
}

}  // namespace sphray::test
