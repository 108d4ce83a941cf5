// The neighbours of a node in a cubic lattice: the sums over a full lattice
// that set the solvers' constants (the particle volume, the presence lobe,
// PBF's relaxation scale), and two spectrum bounds: the density
// constraint's Jacobi iteration (PBF's rest weights, DFSPH's Jacobi weight)
// and DFSPH's explicit viscosity (its step limit).
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

namespace sphray {

// Calls f(x, y, z, r) for every other node (x, y, z) dx of a cubic lattice
// of spacing dx within `support` of a node, r its distance.
template <class F>
void for_lattice_neighbours(double support, double dx, F&& f) {
  const int m = int(std::ceil(support / dx));
  for (int z = -m; z <= m; ++z)
    for (int y = -m; y <= m; ++y)
      for (int x = -m; x <= m; ++x) {
        const double r = dx * std::sqrt(double(x * x + y * y + z * z));
        if ((x || y || z) && r < support) f(x, y, z, r);
      }
}

// The largest of f(k) over the wave vectors k of a grid of `n` steps per
// axis on [0, pi / dx]^3, of its points with k_x >= k_y >= k_z: the whole
// Brillouin zone of a cubic lattice of spacing dx for an f that is even in
// each component of k and unchanged when the axes are permuted (as the
// lattice's neighbours are).
template <class F>
double max_over_lattice_modes(double dx, int n, F&& f) {
  const double step = std::acos(-1.0) / (dx * n);
  double best = 0;
  for (int a = 0; a <= n; ++a)
    for (int b = 0; b <= a; ++b)
      for (int c = 0; c <= b; ++c) best = std::max(best, f(Eigen::Vector3d(a * step, b * step, c * step)));
  return best;
}

// The largest eigenvalue of D^-1 A on a cubic lattice of spacing dx, A = J J^T
// of the density constraint's gradients (PBF's constraint, DFSPH's pressure
// system: a particle's density change from the pressure accelerations) and D
// its diagonal, for a kernel with support s and gradient dW_over_r(r)
// (grad W(d) = d dW_over_r). A mode of wave vector k has the eigenvalue
// p(k) = |h(k)|^2 / sum_d |grad W(d)|^2, h(k) = sum_d sin(k.d) grad W(d) over
// the lattice neighbours d; this is its maximum over `n` steps per axis
// (max_over_lattice_modes).
template <class DwOverR>
double lattice_spectrum_bound(double s, double dx, DwOverR dW_over_r, int n = 24) {
  struct Term {
    Eigen::Vector3d d, g;
  };
  std::vector<Term> terms;
  double g2 = 0;
  for_lattice_neighbours(s, dx, [&](int x, int y, int z, double r) {
    const Eigen::Vector3d d(x * dx, y * dx, z * dx);
    terms.push_back({d, dW_over_r(r) * d});
    g2 += terms.back().g.squaredNorm();
  });
  if (g2 <= 0) return 0;
  return max_over_lattice_modes(dx, n, [&](const Eigen::Vector3d& k) {
    Eigen::Vector3d h = Eigen::Vector3d::Zero();
    for (const Term& t : terms) h += std::sin(k.dot(t.d)) * t.g;
    return h.squaredNorm() / g2;
  });
}

// The largest decay rate, per unit kinematic viscosity nu, of the explicit
// SPH viscosity a_i = 2 (d + 2) nu sum_j V (v_ij . x_ij) / (|x_ij|^2 + eta2)
// grad W_ij (DFSPH's, Monaghan 2005) on a cubic lattice of spacing dx
// [1 / m^2]: a velocity mode e exp(i k.x) decays at the eigenvalues of
//   M(k) = -2 (d + 2) V sum_d (1 - cos k.d) dW_over_r(|d|) / (|d|^2 + eta2) d d^T,
// and an explicit step of dt grows it where dt nu lambda > 2. The maximum
// over `n` steps per axis (max_over_lattice_modes).
template <class DwOverR>
double lattice_viscous_rate_bound(double s, double dx, double volume, double eta2, DwOverR dW_over_r, int n = 24) {
  struct Term {
    Eigen::Vector3d d;
    double f;
  };
  std::vector<Term> terms;
  for_lattice_neighbours(s, dx, [&](int x, int y, int z, double r) {
    terms.push_back({Eigen::Vector3d(x * dx, y * dx, z * dx), -10.0 * volume * dW_over_r(r) / (r * r + eta2)});
  });
  return max_over_lattice_modes(dx, n, [&](const Eigen::Vector3d& k) {
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    for (const Term& t : terms) m += ((1.0 - std::cos(k.dot(t.d))) * t.f) * t.d * t.d.transpose();
    return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
  });
}

}  // namespace sphray
