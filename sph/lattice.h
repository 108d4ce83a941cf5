// The neighbours of a node in a cubic lattice: the sums over a full lattice
// that set the solvers' constants (the particle volume, the presence lobe,
// PBF's relaxation scale), and the spectrum bound of the density
// constraint's Jacobi iteration (PBF's rest weights, DFSPH's relaxation).
#pragma once

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

// The largest eigenvalue of D^-1 A on a cubic lattice of spacing dx, A = J J^T
// of the density constraint's gradients (PBF's constraint, DFSPH's pressure
// system: a particle's density change from the pressure accelerations) and D
// its diagonal, for a kernel with support s and gradient dW_over_r(r)
// (grad W(d) = d dW_over_r). A mode of wave vector k has the eigenvalue
// p(k) = |h(k)|^2 / sum_d |grad W(d)|^2, h(k) = sum_d sin(k.d) grad W(d) over
// the lattice neighbours d; this is the maximum of p(k) over a grid of `n`
// steps per axis on [0, pi / dx]^3 (p is even in each component of k), of its points with k_x >= k_y >= k_z
// (the lattice's neighbours, and so p, do not change when the axes are
// permuted).
template <class DwOverR>
double lattice_spectrum_bound(double s, double dx, DwOverR dW_over_r, int n = 24) {
  struct Term {
    double d[3], g[3];
  };
  std::vector<Term> terms;
  double g2 = 0;
  for_lattice_neighbours(s, dx, [&](int x, int y, int z, double r) {
    const double f = dW_over_r(r);
    Term t{{x * dx, y * dx, z * dx}, {x * dx * f, y * dx * f, z * dx * f}};
    g2 += (t.g[0] * t.g[0] + t.g[1] * t.g[1] + t.g[2] * t.g[2]);
    terms.push_back(t);
  });
  if (g2 <= 0) return 0;
  const double pi = std::acos(-1.0), step = pi / (dx * n);
  double best = 0;
  for (int a = 0; a <= n; ++a)
    for (int b = 0; b <= a; ++b)
      for (int c = 0; c <= b; ++c) {
        const double k[3] = {a * step, b * step, c * step};
        double h[3] = {0, 0, 0};
        for (const Term& t : terms) {
          const double sn = std::sin(k[0] * t.d[0] + k[1] * t.d[1] + k[2] * t.d[2]);
          for (int i = 0; i < 3; ++i) h[i] += sn * t.g[i];
        }
        best = std::max(best, (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) / g2);
      }
  return best;
}

}  // namespace sphray
