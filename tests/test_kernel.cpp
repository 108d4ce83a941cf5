// Kernel functions against double-precision quadrature and finite differences.
#include <cmath>
#include <limits>
#include <type_traits>

#include "sph/kernel.h"
#include "catch.h"

using namespace sphray;

TEST_CASE("kernels integrate to one over their support", "[kernel][cpu]") {
  for (KernelType t : {KernelType::WendlandC2, KernelType::CubicSpline}) {
    const auto k = SmoothingKernel<double>::make(t, 0.013);
    const int n = 200000;
    double sum = 0;
    const double dr = k.support() / n;
    for (int i = 0; i < n; ++i) {
      const double r = (i + 0.5) * dr;
      sum += 4 * M_PI * r * r * k.W(r) * dr;
    }
    CHECK(std::abs(sum - 1.0) < 1e-6);
    CHECK(k.W(k.support()) == 0.0);
    CHECK(k.W(1.01 * k.support()) == 0.0);
  }
}

TEST_CASE("kernel gradient matches a central finite difference", "[kernel][cpu]") {
  for (KernelType t : {KernelType::WendlandC2, KernelType::CubicSpline}) {
    const auto k = SmoothingKernel<double>::make(t, 0.02);
    for (double q = 0.05; q < 1.99; q += 0.07) {
      const double r = q * k.h, e = 1e-7;
      const double fd = (k.W(r + e) - k.W(r - e)) / (2 * e);
      CHECK(std::abs(k.dW_over_r(r) * r - fd) < 1e-6 * std::abs(k.sigma / k.h));
    }
  }
}

TEST_CASE("float kernel agrees with the double reference", "[kernel][cpu]") {
  for (KernelType t : {KernelType::WendlandC2, KernelType::CubicSpline}) {
    const auto kd = SmoothingKernel<double>::make(t, 0.013);
    const auto kf = SmoothingKernel<float>::make(t, 0.013f);
    for (double q = 0; q < 2.0; q += 0.01) {
      const double r = q * kd.h;
      CHECK(std::abs(kf.W(float(r)) - kd.W(r)) <= 1e-5 * kd.W(0));
      CHECK(std::abs(kf.dW_over_r(float(r)) - kd.dW_over_r(r)) <= 1e-5 * std::abs(kd.dW_over_r(0)));
      // The loops' form on r^2 (DFSPH's passes).
      CHECK(std::abs(kf.dW_over_r_sq(float(r * r)) - kd.dW_over_r(r)) <= 1e-5 * std::abs(kd.dW_over_r(0)));
      CHECK(kd.dW_over_r_sq(r * r) == Approx(kd.dW_over_r(r)).epsilon(1e-12).margin(1e-12 * std::abs(kd.dW_over_r(0))));
    }
    // At the support the kernel is continuous (r from rsqrt may round just inside); beyond it, zero.
    CHECK(std::abs(kf.dW_over_r_sq(4.0f * kf.h * kf.h)) <= 1e-5 * std::abs(kd.dW_over_r(0)));
    CHECK(kf.dW_over_r_sq(4.1f * kf.h * kf.h) == 0.0f);
    CHECK(kf.dW_over_r_sq(1e-40f) == kf.dW_over_r(0.0f));  // subnormal r^2: r = 0, no NaN
    CHECK(fast_sqrt(1e-40f) == 0.0f);
    CHECK(fast_sqrt(2.25f) == Approx(1.5f).epsilon(1e-6));
  }
}

TEST_CASE("the loops' compile-time kernels agree with the double reference", "[kernel][cpu]") {
  // dW_over_r_for<K> (interaction.h's pair loop) and W_for<K> (boundary.h's
  // wall pressure) against the double kernel inside the support, zero beyond
  // it (the GPU masks keep pairs a hair beyond), and dW_over_r_for zero for
  // the NaN distance that r2 * rsqrt(r2) gives a coincident pair.
  const auto check = [](auto tag) {
    constexpr KernelType t = decltype(tag)::value;
    const auto kd = SmoothingKernel<double>::make(t, 0.013);
    const auto kf = SmoothingKernel<float>::make(t, 0.013f);
    for (double q = 0; q < 2.0; q += 0.01) {
      const double r = q * kd.h;
      CHECK(std::abs(kf.template dW_over_r_for<t>(float(r)) - kd.dW_over_r(r)) <= 1e-5 * std::abs(kd.dW_over_r(0)));
      CHECK(std::abs(kf.template W_for<t>(float(r)) - kd.W(r)) <= 1e-5 * kd.W(0));
    }
    for (double q = 2.0; q < 2.2; q += 0.001) {
      CHECK(kf.template dW_over_r_for<t>(float(q * kd.h)) == 0.0f);
      CHECK(kf.template W_for<t>(float(q * kd.h)) == 0.0f);
    }
    CHECK(kf.template dW_over_r_for<t>(kf.support()) == 0.0f);
    CHECK(kf.template W_for<t>(kf.support()) == 0.0f);
    CHECK(kf.template dW_over_r_for<t>(std::numeric_limits<float>::quiet_NaN()) == 0.0f);
  };
  check(std::integral_constant<KernelType, KernelType::WendlandC2>{});
  check(std::integral_constant<KernelType, KernelType::CubicSpline>{});
}
