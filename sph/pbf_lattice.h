// PBF's constants from a full cubic lattice (host side, once per scene): the
// particle volume and the scale of the constraint's denominator that
// make_pbf_params sets from them, and the push of the artificial pressure
// s_corr on a flat free surface, which the scene's s_corr options are
// checked against (sph/config.cpp).
#pragma once

#include <cmath>

#include "lattice.h"
#include "pbf_kernel.h"

namespace sphray {

struct PbfLatticeScales {
  double volume;  // m / rho0 that gives a full lattice exactly the rest density (poly6 sums to about 1 / dx^3)
  double g0;      // sum_j |grad_j C_i|^2 there: the scale of the relaxation and of s_corr
};

inline PbfLatticeScales pbf_lattice_scales(const PbfKernel<double>& k, double dx) {
  double w_sum = 0, g2_sum = 0;
  for_lattice_neighbours(k.support(), dx, [&](int, int, int, double r) {
    w_sum += k.W(r * r);
    g2_sum += r * r * k.dW_over_r(r) * k.dW_over_r(r);
  });
  const double volume = 1.0 / (k.W(0) + w_sum);
  return {volume, volume * volume * g2_sum};
}

// How far s_corr = -k (W / W(dq))^n alone moves a particle of a flat free
// surface of a lattice in one iteration, in spacings (support and dq in
// spacings and supports, as the scene gives them): the particle's
// neighbours lie at and below its layer, the lambdas of an uncompressed
// surface are zero, and the correction (pbf.h, Correct) is
//   dx_i = V sum_j s_corr(r_ij) grad W_ij,  s_corr = -(k / G0) (W(r_ij) / W(dq))^n,
// outward. Infinite where W(dq) = 0 (dq at the support).
inline double scorr_surface_push(double support, double k, double dq, int n) {
  if (k == 0) return 0;  // s_corr off (the default)
  const PbfKernel<double> kernel = PbfKernel<double>::make(support);
  const double w_dq = kernel.W(dq * dq * support * support);
  if (!(w_dq > 0)) return HUGE_VAL;
  const PbfLatticeScales scales = pbf_lattice_scales(kernel, 1.0);
  double up = 0;
  for_lattice_neighbours(support, 1.0, [&](int, int, int z, double r) {
    if (z > 0) return;  // above the surface: no particle
    const double s_corr = -(k / scales.g0) * std::pow(kernel.W(r * r) / w_dq, n);
    up += scales.volume * s_corr * (-z) * kernel.dW_over_r(r);  // z of grad W_ij, x_i - x_j = (0, 0, -z)
  });
  return up;
}

// The largest push scorr_surface_push may give (spacings per iteration):
// what pbf.scorr_k = 1 gives at the default dq (0.2 supports) and n (4),
// 0.048. Above it the dam break's free surface was thrown off
// (docs/method.md, "s_corr").
constexpr double kMaxScorrPush = 0.05;

}  // namespace sphray
