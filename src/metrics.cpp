#include "metrics.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace sphray {

double surge_front(const HostParticles& p, double back_wall_x, double spacing) {
  double front = back_wall_x;
  for (const auto& x : p.pos) front = std::max(front, double(x.x) + 0.5 * spacing);
  return front - back_wall_x;
}

double kinetic_energy(const HostParticles& p, double particle_mass) {
  double e = 0;
  for (const auto& v : p.vel) e += 0.5 * particle_mass * double(length2(v));
  return e;
}

Curve read_csv_curve(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("cannot open '" + path + "'");
  Curve c;
  bool header = false;
  for (std::string line; std::getline(f, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    double a, b;
    if (!(ss >> a >> b)) {
      if (!header && c.x.empty()) { header = true; continue; }
      throw std::runtime_error(path + ": cannot read two numbers from line '" + line + "'");
    }
    c.x.push_back(a);
    c.y.push_back(b);
  }
  if (c.x.empty()) throw std::runtime_error(path + ": no data");
  return c;
}

double interpolate(const Curve& c, double x) {
  if (x <= c.x.front()) return c.y.front();
  if (x >= c.x.back()) return c.y.back();
  const size_t k = size_t(std::upper_bound(c.x.begin(), c.x.end(), x) - c.x.begin());
  const double t = (x - c.x[k - 1]) / (c.x[k] - c.x[k - 1]);
  return c.y[k - 1] + t * (c.y[k] - c.y[k - 1]);
}

CurveError relative_error(const Curve& sim, const Curve& experiment) {
  CurveError e;
  double sum = 0;
  for (size_t k = 0; k < experiment.x.size(); ++k) {
    if (experiment.x[k] > sim.x.back() + 1e-12) continue;
    const double r = (interpolate(sim, experiment.x[k]) - experiment.y[k]) / experiment.y[k];
    sum += r * r;
    e.max_relative = std::max(e.max_relative, std::abs(r));
    ++e.points;
  }
  e.rms_relative = e.points ? std::sqrt(sum / double(e.points)) : 0.0;
  return e;
}

}  // namespace sphray
