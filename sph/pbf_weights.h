// The weights of lambda in PBF's iterations at rest (pbf.rest_weights,
// docs/method.md, "Position-based fluids"): host-side, computed once per scene.
//
// One Jacobi iteration of the density constraint moves the constraint errors
// by (I - w D^-1 A), A = J J^T of the constraint gradients, D its diagonal
// plus the relaxation. On a lattice a constraint mode of wave vector k has
// the eigenvalue p(k) = |h(k)|^2 / sum_d |grad W(d)|^2 of D^-1 A, with
// h(k) = sum_d sin(k.d) grad W(d) over the lattice neighbours d; at the
// default support (2.1 spacings, spiky gradient) p reaches 3.03, and relaxed
// (below) 3.0, 3.26 and 3.38 on lattices jittered by 0.1, 0.2 and 0.3
// spacing (tests/test_pbf.cpp, dense). With lambda as is (w = 1 /
// (1 + relaxation)) the modes near the top grow by up to 1.75x per iteration;
// and as velocities are position changes over dt a mode that K iterations
// leave at mu follows e_{n+1} = mu (2 e_n - e_{n-1}) from step to step,
// stable only for -1/3 < mu < 1. A liquid at rest then keeps jittering.
//
// The weights at rest come from the roots of a shifted Chebyshev polynomial,
// q(p) = (T_K(y(p)) + a) / (T_K(y(0)) + a) with y mapping [d, P] onto
// [1, -1]: iteration k scales lambda by 1 / r_k (r_k the roots, the largest
// first), so that after K iterations every mode in [d, P] is left at
// q(p) in [(a - 1), (a + 1)] / (T_K(y(0)) + a), above -1/3, and a slow mode
// below d is reduced by about (sum_k 1 / r_k) p (K p by K plain iterations;
// 2.67 p against 3 p at K = 3). Applied while the liquid is at rest only
// (Lambda, pbf.h): in a flowing liquid the plain iteration's overshoot,
// undone only where it compresses, acts as extra stiffness.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

namespace sphray {

// The relaxed spectrum's bound P that the weights cover: the lattice's bound
// times kDisorder (a disordered liquid's modes reach 1.1-1.15x the lattice's),
// over 1 + relaxation (D gains the relaxation, a share of the lattice's D).
struct PbfRestSpectrum {
  static constexpr double kDisorder = 1.2;
  static constexpr double kShift = 0.6;     // a: q stays above -(1 - a) / (T_K(y(0)) + a)
  static constexpr double kLowEdge = 0.06;  // d = kLowEdge P: the slow modes below it keep the plain iteration's reduction
  static double top(double lattice_bound, double relaxation) { return kDisorder * lattice_bound / (1.0 + relaxation); }
};

// The K weights of lambda, in iteration order (the smallest first: a large
// weight first threw the fast modes before the others had settled).
inline std::vector<double> pbf_rest_weights(int K, double top) {
  const double a = PbfRestSpectrum::kShift, d = PbfRestSpectrum::kLowEdge * top;
  const double pi = std::acos(-1.0);
  std::vector<double> roots;
  for (int j = 0; j < K; ++j) {
    const double y = std::cos((std::acos(-a) + 2.0 * pi * j) / K);
    roots.push_back(d + (1.0 - y) * (top - d) / 2.0);
  }
  std::sort(roots.begin(), roots.end(), std::greater<double>());
  std::vector<double> w;
  for (double r : roots) w.push_back(1.0 / r);
  return w;
}

}  // namespace sphray
