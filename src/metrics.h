// Quantities measured on a particle state, and their comparison with
// experiments: the surge front of a dam break (Martin & Moyce 1952).
#pragma once

#include <string>
#include <vector>

#include "solver.h"

namespace sphray {

// Leading edge of the liquid along +x, measured from back_wall_x [m]: the
// foremost particle centre plus half a spacing (a particle's own extent), so a
// column of width a at rest reads exactly a.
double surge_front(const HostParticles& p, double back_wall_x, double spacing);

double kinetic_energy(const HostParticles& p, double particle_mass);

struct Curve {
  std::vector<double> x, y;
};

// Reads a two-column CSV (lines starting with '#' and one header line skipped).
Curve read_csv_curve(const std::string& path);

// Linear interpolation of a curve sampled at increasing x; clamps at the ends.
double interpolate(const Curve& c, double x);

// RMS of (sim(T) - exp(T)) / exp(T) over the experimental points with T <= sim's last T.
struct CurveError {
  double rms_relative = 0, max_relative = 0;
  size_t points = 0;
};
CurveError relative_error(const Curve& sim, const Curve& experiment);

}  // namespace sphray
