// Position-based fluids (sph/pbf.h): its kernels against numerical integrals
// in double, the rest state at the mirror walls, the guards, and the scene's
// "pbf" options. The physics studies (front, stress suite, column at rest)
// are [slow].
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "catch.h"
#include "helpers.h"
#include "nsearch_probe.h"
#include "sph/lattice.h"
#include "sph/pbf.h"
#include "sph/pbf_kernel.h"
#include "sph/pbf_lattice.h"
#include "sph/pbf_weights.h"

using namespace sphray;

namespace {

// The integral over the plane at distance z from a point of a radial kernel
// w(r): 2 pi int_0^sqrt(s^2 - z^2) w(sqrt(rho^2 + z^2)) rho d rho (midpoint rule).
template <class W>
double plane_integral(double s, double z, W w) {
  const double R = std::sqrt(std::max(s * s - z * z, 0.0));
  const int n = 4000;
  double sum = 0;
  for (int k = 0; k < n; ++k) {
    const double rho = (k + 0.5) * R / n;
    sum += w(std::sqrt(rho * rho + z * z)) * rho;
  }
  return 2 * M_PI * sum * R / n;
}

// L^3 particles in a periodic box (nominal spacing 1, jittered by up to
// `jitter` per axis from `seed`): f(i, m, d, r) for every ordered pair i != m
// within `support`, d = x_i - x_m the nearest periodic offset, r = |d|.
template <class F>
void for_periodic_pairs(int L, double jitter, unsigned seed, double support, F&& f) {
  const int n = L * L * L;
  std::vector<Eigen::Vector3d> x(n);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  for (int i = 0; i < n; ++i) x[i] = Eigen::Vector3d(i % L, (i / L) % L, i / (L * L)) + Eigen::Vector3d(u(rng), u(rng), u(rng));
  for (int i = 0; i < n; ++i)
    for (int m = 0; m < n; ++m) {
      if (m == i) continue;
      Eigen::Vector3d d = x[i] - x[m];
      for (int c = 0; c < 3; ++c) d[c] -= L * std::round(d[c] / L);
      const double r = d.norm();
      if (r < support) f(i, m, d, r);
    }
}

// The eigenvalues of (D + eps)^-1 A, A = J J^T of the density
// constraints C_i = sum_j V W(x_i - x_j) of L^3 particles in a periodic box
// (for_periodic_pairs), D = diag(A) and
// eps = relaxation x (the lattice's D): dense, with Eigen (V = 1: the
// spectrum does not depend on it). DFSPH's pressure system has the same
// operator (its D^-1 the DFSPH factor, no relaxation), with its own kernel.
template <class K>
Eigen::VectorXd dense_spectrum(const K& k, int L, double jitter, double relaxation) {
  const int n = L * L * L;
  // J: rows the constraints, columns the 3n coordinates.
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(n, 3 * n);
  for_periodic_pairs(L, jitter, 7, k.support(), [&](int i, int m, const Eigen::Vector3d& d, double r) {
    const Eigen::Vector3d g = k.dW_over_r(r) * d;  // grad_i W(x_i - x_m), V = 1
    J.block<1, 3>(i, 3 * i) += g.transpose();
    J.block<1, 3>(i, 3 * m) -= g.transpose();
  });
  const Eigen::MatrixXd A = J * J.transpose();
  double g0 = 0;  // the lattice's D: sum_d |grad W(d)|^2
  for_lattice_neighbours(k.support(), 1.0, [&](int x, int y, int z, double r) {
    g0 += (k.dW_over_r(r) * Eigen::Vector3d(x, y, z)).squaredNorm();
  });
  const Eigen::VectorXd s = (A.diagonal().array() + relaxation * g0).rsqrt();
  const Eigen::MatrixXd B = s.asDiagonal() * A * s.asDiagonal();
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(B, Eigen::EigenvaluesOnly).eigenvalues();
}

Scene pbf_scene(const std::string& file, std::vector<std::string> overrides) {
  overrides.push_back("sph.solver=pbf");
  return load_scene(test::source_path(file), overrides);
}

}  // namespace

TEST_CASE("pbf kernels: poly6 integrates to one, the spiky gradient is the derivative of its kernel", "[sph][cpu]") {
  const PbfKernel<double> k = PbfKernel<double>::make(0.03);
  const double s = k.s;
  // Volume integral of poly6 as the sum of its plane integrals.
  double total = 0;
  const int n = 400;
  for (int i = 0; i < n; ++i) {
    const double z = -s + (i + 0.5) * 2 * s / n;
    total += plane_integral(s, std::abs(z), [&](double r) { return k.W(r * r); }) * 2 * s / n;
  }
  CHECK(std::abs(total - 1.0) < 1e-4);
  for (double r : {0.1 * s, 0.5 * s, 0.9 * s}) {
    const double h = 1e-7 * s;
    auto spiky = [&](double x) { return -k.spiky / 3 * std::pow(s - x, 3); };  // 15 / (pi s^6) (s - r)^3
    CHECK(std::abs(k.dW_over_r(r) * r - (spiky(r + h) - spiky(r - h)) / (2 * h)) < 1e-6 * std::abs(k.dW_over_r(r) * r));
  }
  CHECK(k.dW_over_r(0.0) == 0.0);
  CHECK(k.dW_over_r(s) == 0.0);
  // The loops' folded forms: poly6 taken out of W, a constant into the gradient.
  for (double r : {0.0, 0.3 * s, 0.99 * s, s, 1.5 * s}) {
    CHECK(k.poly6 * k.W_over_poly6(r * r) == Approx(k.W(r * r)).epsilon(1e-14).margin(1e-14 * k.W(0)));
    CHECK(k.scaled_dW_over_r_sq(r * r, 3.0 * k.spiky) == Approx(3.0 * k.dW_over_r_sq(r * r)).epsilon(1e-14));
  }
  CHECK(k.W_over_poly6(1.5 * s * s) == 0.0);
  // The loops' form on the squared distance, in float, against the double one on r.
  const PbfKernel<float> kf = PbfKernel<float>::make(float(s));
  const double peak = std::abs(k.dW_over_r(1e-3 * s));
  for (int i = 1; i <= 1000; ++i) {
    const double r = s * i / 1000.0;
    const float r2 = float(r * r);
    CHECK(std::abs(double(kf.dW_over_r_sq(r2)) - k.dW_over_r(std::sqrt(double(r2)))) <= 1e-5 * peak);
    CHECK(k.dW_over_r_sq(r * r) == Approx(k.dW_over_r(r)).epsilon(1e-12).margin(1e-12 * peak));
  }
  CHECK(kf.dW_over_r_sq(0.0f) == 0.0f);
  CHECK(kf.dW_over_r_sq(1e-40f) == 0.0f);  // subnormal: no direction, no NaN
  CHECK(kf.dW_over_r_sq(kf.s * kf.s) == 0.0f);
  CHECK(kf.dW_over_r_sq(2.0f * kf.s * kf.s) == 0.0f);
}

TEST_CASE("pbf and dfsph: a block in a corner without gravity has the rest density, walls included, and stays still",
          "[sph][cpu]") {
  // The block fills the tank's corner at x, y, z < 0.08: at the three walls the
  // mirror images continue the lattice exactly, so every particle farther than
  // a support from the block's free faces has the lattice's density, rho0.
  const std::string kind = GENERATE(std::string("pbf"), std::string("dfsph"));
  INFO("sph.solver " << kind);
  Scene s = load_scene(test::source_path("scenes/stress/zero_gravity.json"), {"sph.solver=" + kind});
  s.fluid[0].box = {{0.0, 0.0, 0.0}, {0.08, 0.08, 0.08}};
  const ResolvedScene r = resolve_scene(s);
  auto solver = make_cpu_solver(make_solver_input(r, PresenceMode::Off));
  const HostParticles before = solver->download();
  test::run_until(*solver, 0.1);
  const HostParticles after = solver->download();
  const double dx = s.sph.spacing, support = kind == "pbf" ? r.pbf.kernel.s : r.dfsph.kernel.support();
  std::vector<Vec3f> start(before.pos.size());
  for (size_t k = 0; k < before.pos.size(); ++k) start[before.id[k]] = before.pos[k];
  size_t checked = 0, at_wall = 0, at_corner = 0;
  for (size_t k = 0; k < after.pos.size(); ++k) {
    const Vec3f p = after.pos[k];
    const Box& b = s.fluid[0].box;
    if (std::min({b.max.x - p.x, b.max.y - p.y, b.max.z - p.z}) > support) {
      CHECK(std::abs(after.density[k] / s.sph.rest_density - 1.0) < 1e-4);
      ++checked;
      at_wall += std::min({p.x, p.y, p.z}) < dx ? 1 : 0;
      at_corner += std::max({p.x, p.y, p.z}) < dx ? 1 : 0;
    }
    CHECK(length(p - start[after.id[k]]) < 0.05 * dx);
  }
  CHECK(checked > 0);
  CHECK(at_wall > 0);
  CHECK(at_corner == 1);
  CHECK(solver->last_solve().density_error_max < 0.01);
}

TEST_CASE("pbf s_corr: one iteration moves a flat free surface's particles by the push the scene check bounds",
          "[sph][cpu]") {
  // The block in the corner of the test above, released without gravity:
  // every lambda is zero (the lattice at rest density, its surface below
  // it), so one iteration moves a particle of the top face, away from the
  // block's free sides, by s_corr alone: scorr_surface_push spacings up.
  const auto [k, n] = GENERATE(std::pair<double, int>{1.0, 4}, std::pair<double, int>{0.1, 1},
                               std::pair<double, int>{0.25, 2});
  INFO("pbf.scorr_k " << k << ", pbf.scorr_n " << n);
  Scene s = pbf_scene("scenes/stress/zero_gravity.json",
                      {"pbf.iterations=1", "pbf.scorr_k=" + std::to_string(k), "pbf.scorr_n=" + std::to_string(n)});
  s.fluid[0].box = {{0.0, 0.0, 0.0}, {0.08, 0.08, 0.08}};
  const ResolvedScene r = resolve_scene(s);
  auto solver = make_cpu_solver(make_solver_input(r, PresenceMode::Off));
  const HostParticles before = solver->download();
  solver->step(1.0);
  const HostParticles after = solver->download();
  const double dx = s.sph.spacing, support = r.pbf.kernel.s;
  const double push = scorr_surface_push(s.sph.pbf.support, k, s.sph.pbf.scorr_dq, n);
  CHECK(push > 0.02);
  CHECK(push <= kMaxScorrPush);
  std::vector<Vec3f> start(before.pos.size());
  for (size_t i = 0; i < before.pos.size(); ++i) start[before.id[i]] = before.pos[i];
  size_t checked = 0;
  for (size_t i = 0; i < after.pos.size(); ++i) {
    const Vec3f p0 = start[after.id[i]];
    if (p0.z < 0.08 - dx || std::max(p0.x, p0.y) > 0.08 - support) continue;
    const Vec3f d = after.pos[i] - p0;
    CHECK(d.z / dx == Approx(push).epsilon(1e-3));
    CHECK(std::hypot(d.x, d.y) < 1e-4 * dx);
    ++checked;
  }
  CHECK(checked == 36);  // the top face's 6 x 6 within a support of no free side
}

TEST_CASE("pbf and dfsph keep the ids they are given (a resumed run's, a rank's share)", "[sph][cpu]") {
  for (const char* solver : {"pbf", "dfsph"}) {
    INFO(solver);
    const Scene s = load_scene(test::source_path("scenes/dam_break.json"),
                               {"sph.spacing=0.04", std::string("sph.solver=") + solver});
    SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
    // Every third particle, numbered as if the others had left: ids 7, 10, 13, ...
    SolverInput part = in;
    part.fluid_pos_rho.clear();
    part.fluid_vel.clear();
    std::vector<Vec3f> start;
    for (size_t i = 0; i < in.fluid_pos_rho.size(); i += 3) {
      part.fluid_pos_rho.push_back(in.fluid_pos_rho[i]);
      part.fluid_vel.push_back(in.fluid_vel[i]);
      part.fluid_id.push_back(uint32_t(7 + i));
      start.push_back(xyz(in.fluid_pos_rho[i]));
    }
    auto solver_ = make_cpu_solver(part);
    for (int k = 0; k < 3; ++k) solver_->step(1.0);
    const HostParticles h = solver_->download();
    REQUIRE(h.id.size() == start.size());
    std::vector<bool> seen(start.size(), false);
    for (size_t j = 0; j < h.id.size(); ++j) {
      const uint32_t i = h.id[j] - 7;
      REQUIRE(i % 3 == 0);
      REQUIRE(i / 3 < start.size());
      CHECK(!seen[i / 3]);
      seen[i / 3] = true;
      // Its own particle: three steps move it less than a spacing.
      CHECK(std::sqrt(length2(h.pos[j] - start[i / 3])) < s.sph.spacing);
    }
  }
}

TEST_CASE("pbf: no particle leaves a closed tank or comes closer to a wall than pbf.wall_margin, and the step follows the flow CFL",
          "[sph][cpu]") {
  const Scene s = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.04", "run.end_time=0.6"});
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const size_t n = solver->num_fluid();
  Aabb tank = resolve_scene(s).params.tank;  // the walls in the solver's single precision
  const float margin = float(0.999 * s.sph.pbf.wall_margin * s.sph.spacing);
  REQUIRE(margin > 0.0f);
  tank.min = tank.min + Vec3f{margin, margin, margin};
  tank.max = tank.max - Vec3f{margin, margin, margin};
  double worst_cfl = 0;
  while (solver->time() < s.run.end_time - 1e-12) {
    solver->step(s.run.end_time);
    const StepLimits& l = solver->last_limits();
    worst_cfl = std::max(worst_cfl, l.dt * l.max_speed / s.sph.spacing);
    const HostParticles p = solver->download();
    REQUIRE(p.pos.size() == n);
    for (const Vec3f& x : p.pos) REQUIRE(test::inside(x, tank));
  }
  // dt <= cfl dx / v_max at the speed the step started from, a step landed
  // on the end time stretched by up to kLandStretch.
  CHECK(worst_cfl <= ChooseFlowStep::kLandStretch * s.sph.cfl + 1e-9);
  CHECK(solver->last_solve().iterations == s.sph.pbf.iterations);
}

// A particle projected onto a wall coincides with its own mirror image,
// which adds W(0) to its density and no gradient to push it off (three
// images at an edge): such particles were the dam break's most compressed
// (and, with static images, its fastest; with mirrored images this run's
// largest speed is the same, 2.62 m/s, either way). The margin keeps the
// image a fifth of a spacing away.
TEST_CASE("pbf: the wall margin keeps particles pressed against the walls from over-compressing", "[sph][cpu]") {
  auto run = [](const std::string& margin) {
    const Scene s = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.03", "run.end_time=0.6", "pbf.wall_margin=" + margin});
    auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
    double worst = 0;
    while (solver->time() < s.run.end_time - 1e-12) {
      solver->step(s.run.end_time);
      worst = std::max(worst, solver->last_solve().density_error_max);
    }
    return worst;
  };
  const double on = run("0.1"), off = run("0");
  INFO("largest compression of one particle " << off << " -> " << on);
  CHECK(on < 0.1);
  CHECK(on < 0.5 * off);
}

// A free-slip wall is a mirror: with mirrored images (pbf.images, the
// default) a column collapsing from the wall at x = 0 moves as the half x > 0
// of a column twice as wide collapsing from its middle in a tank with no wall
// there. The reference is that explicit run (each particle's mirror a
// particle of its own, its lambda and its velocity in the XSPH sum its own);
// static images, which push with the particle's lambda alone, do not follow it.
TEST_CASE("pbf: with mirrored images a free-slip wall corrects as the liquid mirrored across it", "[sph][cpu]") {
  auto run = [](const Scene& s) {
    auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
    test::run_until(*solver, 0.02);  // 6 steps: beyond them round-off grows, as between any two orders of the sums
    return solver->download();
  };
  // With s_corr (pbf.scorr_k 1) the images push as the mirrored liquid too.
  const double scorr = GENERATE(0.0, 1.0);
  INFO("pbf.scorr_k " << scorr);
  Scene wall = pbf_scene("scenes/stress/zero_gravity.json",
                         {"gravity=[0,0,-9.81]", "run.end_time=0.02", "pbf.scorr_k=" + std::to_string(scorr)});
  wall.tank = {{0.0, 0.0, 0.0}, {0.3, 0.1, 0.2}};
  wall.fluid[0].box = {{0.0, 0.0, 0.0}, {0.1, 0.1, 0.1}};
  Scene mirrored = wall;
  mirrored.tank.min.x = -0.3;
  mirrored.fluid = {FluidBlock{{{-0.1, 0.0, 0.0}, {0.0, 0.1, 0.1}}}, wall.fluid[0]};
  const HostParticles ref = run(mirrored);
  const size_t n = ref.pos.size() / 2;  // ids n.. are the block at x > 0, in the order of the wall run's
  std::vector<Vec3f> expect(n);
  for (size_t k = 0; k < ref.pos.size(); ++k)
    if (ref.id[k] >= n) expect[ref.id[k] - n] = ref.pos[k];
  auto deviation = [&](const HostParticles& got) {
    REQUIRE(got.pos.size() == n);
    double worst = 0;
    for (size_t k = 0; k < n; ++k) worst = std::max(worst, double(length(got.pos[k] - expect[got.id[k]])));
    return worst / wall.sph.spacing;
  };
  const HostParticles start = make_cpu_solver(make_solver_input(resolve_scene(wall), PresenceMode::Off))->download();
  const HostParticles got = run(wall);
  std::vector<Vec3f> x0(n);
  for (size_t k = 0; k < n; ++k) x0[start.id[k]] = start.pos[k];
  double moved = 0;  // the scale of the test: how far the particles went
  for (size_t k = 0; k < n; ++k) moved = std::max(moved, double(length(got.pos[k] - x0[got.id[k]])) / wall.sph.spacing);
  const double as_mirror = deviation(got);
  Scene statics = wall;
  statics.sph.pbf.mirrored_images = false;
  const double as_static = deviation(run(statics));
  INFO("largest move " << moved << " spacings; from the mirrored run: mirrored images " << as_mirror
                       << ", static images " << as_static << " spacings");
  CHECK(moved > 0.3);
  CHECK(as_mirror < 1e-3);  // 3e-5 measured (3e-4 with s_corr)
  CHECK(as_static > 0.05);  // 0.25 measured (1.6 with s_corr)
}

TEST_CASE("pbf rest weights: the spectrum they cover is the constraint operator's, and K iterations leave every mode in (-1/3, 1]",
          "[sph][cpu]") {
  const PbfKernel<double> k = PbfKernel<double>::make(2.1);  // the default support, spacing 1
  const double bound = lattice_spectrum_bound(k.support(), 1.0, [&](double r) { return k.dW_over_r(r); });
  // The lattice's modes on a periodic 6^3 box are a subset of the k grid's
  // continuum (its largest, 3.03, lies near k = (0.29, 0.29, 0.33) pi).
  const double lattice = dense_spectrum(k, 6, 0.0, 0.0).maxCoeff();
  INFO("k-space bound " << bound << ", dense 6^3 lattice " << lattice);
  CHECK(std::abs(bound - 3.03) < 0.01);
  CHECK(lattice <= bound * (1 + 1e-9));
  CHECK(lattice >= 0.98 * bound);
  const double top = PbfRestSpectrum::top(bound, 0.1);  // the default relaxation
  for (double jitter : {0.0, 0.1, 0.2, 0.3}) {
    // Disordered particles (lattices jittered by up to `jitter` per axis).
    const Eigen::VectorXd p = dense_spectrum(k, 8, jitter, 0.1);
    INFO("jitter " << jitter << ": relaxed spectrum up to " << p.maxCoeff() << ", the weights' top " << top);
    if (jitter <= 0.2) CHECK(p.maxCoeff() < top);
    // K iterations leave a mode of eigenvalue p at q(p) = prod_k (1 - w_k p):
    // the step-to-step recurrence is stable for -1/3 < q <= 1.
    for (int K = 1; K <= PbfParams::kRestWeights; ++K) {
      const std::vector<double> w = pbf_rest_weights(K, top);
      REQUIRE(int(w.size()) == K);
      CHECK(std::is_sorted(w.begin(), w.end()));  // the smallest weight first
      double lowest = 1, highest = -1;
      for (Eigen::Index i = 0; i < p.size(); ++i) {
        double q = 1;
        for (double wk : w) q *= 1 - wk * p[i];
        lowest = std::min(lowest, q);
        highest = std::max(highest, q);
      }
      INFO(K << " iterations: q in [" << lowest << ", " << highest << "]");
      CHECK(lowest > -1.0 / 3.0);
      CHECK(highest <= 1.0 + 1e-9);
    }
  }
}

TEST_CASE("dfsph's Jacobi weight: no mode of the pressure system grows in an iteration, at supports of 1.5-4 "
          "spacings with either kernel",
          "[sph][cpu]") {
  // An iteration leaves a mode of eigenvalue p of D^-1 A at 1 - w p: it grows
  // where w p > 2. The reference: the dense spectrum of 512 particles on a
  // lattice jittered by up to 0.1 spacing (a disordered liquid's), against
  // the weight the scene gets from the lattice's k-space bound.
  for (const KernelType type : {KernelType::CubicSpline, KernelType::WendlandC2})
    for (const double support : {1.5, 2.1, 2.5, 3.0, 4.0}) {
      Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [1,1,1]}, "fluid": [{"min": [0,0,0], "max": [0.5,0.5,0.5]}],
        "sph": {"spacing": 0.1, "solver": "dfsph"}})", "wide.json");
      s.sph.dfsph.kernel = type;
      s.sph.dfsph.support = support;
      const double w = resolve_scene(s).dfsph.jacobi_weight;
      const SmoothingKernel<double> k = SmoothingKernel<double>::make(type, 0.5 * support);  // spacing 1
      const double top = dense_spectrum(k, 8, 0.1, 0.0).maxCoeff();
      INFO((type == KernelType::CubicSpline ? "cubic spline" : "Wendland C2") << ", support " << support
                                                                               << ": weight " << w << ", dense spectrum up to "
                                                                               << top);
      CHECK(w <= 0.5f);
      CHECK(w * top < 2.0);
      if (support == 2.1 && type == KernelType::CubicSpline) CHECK(w == 0.5f);  // the default: SPlisHSPlasH's weight
      // Where 0.5 would let the fastest modes grow.
      if (support >= 3.0) CHECK(0.5 * top > 2.0);
    }
}

TEST_CASE("dfsph's viscous step limit: no velocity mode of a disordered liquid grows in an explicit viscous step",
          "[sph][cpu]") {
  // The explicit viscosity a_i = 10 nu sum_j V (v_ij . x_ij) / (|x_ij|^2 +
  // eta2) grad W_ij of 512 particles in a periodic box (a lattice jittered by
  // up to 0.1 spacing, spacing 1) is dv/dt = -nu M v, M symmetric: a step of
  // dt grows the modes with dt nu lambda > 2. The reference: M's largest
  // eigenvalue, dense; the limit: the scene's max_dt_viscous.
  for (const KernelType type : {KernelType::CubicSpline, KernelType::WendlandC2})
    for (const double support : {2.1, 3.0}) {
      Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [10,10,10]}, "fluid": [{"min": [0,0,0], "max": [5,5,5]}],
        "sph": {"spacing": 1, "solver": "dfsph"}, "dfsph": {"viscosity": 1}})", "viscous.json");
      s.sph.dfsph.kernel = type;
      s.sph.dfsph.support = support;
      const DfsphParams df = resolve_scene(s).dfsph;
      const SmoothingKernel<double> k = SmoothingKernel<double>::make(type, 0.5 * support);
      const int L = 8, n = L * L * L;
      const double eta2 = 0.01 * k.h * k.h, V = df.volume;
      Eigen::MatrixXd M = Eigen::MatrixXd::Zero(3 * n, 3 * n);
      for_periodic_pairs(L, 0.1, 11, k.support(), [&](int i, int j, const Eigen::Vector3d& d, double r) {
        const Eigen::Matrix3d b = (-10.0 * V * k.dW_over_r(r) / (r * r + eta2)) * d * d.transpose();
        M.block<3, 3>(3 * i, 3 * i) += b;  // v_i's own term
        M.block<3, 3>(3 * i, 3 * j) -= b;  // v_j's
      });
      const double top = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
      INFO((type == KernelType::CubicSpline ? "cubic spline" : "Wendland C2") << ", support " << support << ": dt nu lambda = "
                                                                               << df.max_dt_viscous * top);
      CHECK(df.max_dt_viscous * top < 2.0);
    }
}

TEST_CASE("pbf rest weights: a flowing liquid's iterations take lambda as is, a liquid at rest the weights", "[sph][cpu]") {
  // The dam break's column, thrown at 3 m/s or at rest, five steps; flowing
  // above pbf.flow_speed x 3 m/s = 1.5 m/s (the scene's flow speed is its
  // fastest initial speed, at least sqrt(g H)).
  auto run = [](const std::string& weights, float speed) {
    Scene s = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.04", "pbf.flow_speed=0.5", "pbf.rest_weights=" + weights});
    s.fluid[0].velocity = {speed, 0, 0};
    auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
    for (int k = 0; k < 5; ++k) solver->step(1.0);
    return solver->download();
  };
  auto largest_difference = [](const HostParticles& a, const HostParticles& b) {
    REQUIRE(a.id == b.id);
    double d = 0;
    for (size_t i = 0; i < a.pos.size(); ++i) d = std::max(d, double(std::sqrt(length2(a.pos[i] - b.pos[i]))));
    return d;
  };
  const double flowing = largest_difference(run("chebyshev", 3.0f), run("uniform", 3.0f));
  const double resting = largest_difference(run("chebyshev", 0.0f), run("uniform", 0.0f));
  INFO("largest position difference, flowing " << flowing << " m, at rest " << resting << " m");
  CHECK(flowing == 0.0);
  CHECK(resting > 1e-6);
}

TEST_CASE("pbf step size: after the first step the limit follows the mean compression left, never below the depth limit",
          "[sph][cpu]") {
  // One call of the rule on a control whose previous step and error are set;
  // returns the step and the solver's limit. The flow CFL is out of reach
  // (a slow flow, a wide cfl_dx) unless a test asks for it.
  const double depth = 1e-3, target = 0.005, n = 1000;
  // taken: the step as landed (0: the step chosen, dt_before).
  auto choose = [&](double dt_before, double error_mean, double error_smooth, double cfl_dx = 1.0,
                    double remaining = 1.0, double taken = 0.0) {
    FlowControl c{};
    c.stats.max_speed2 = 1.0f;  // 1 m/s
    c.stats.error_sum = error_mean * n;
    c.stats.count = n;
    c.dt_chosen = dt_before;
    c.limits.dt = taken;
    c.error_mean = error_smooth;
    ChooseFlowStep{cfl_dx, 0.0, 1.0, depth, 1e-8, remaining, &c, target}(0);
    return c;
  };
  // The first step: the depth limit, and the smoothed error starts at the step's.
  FlowControl c = choose(0.0, 0.001, 0.0);
  CHECK(c.limits.dt == depth);
  CHECK(c.error_mean == Approx(0.001));
  CHECK(c.dt_chosen == depth);
  // Compression below the target: the step grows as sqrt(target / e), at most 5% a step.
  const double e = target / (1.02 * 1.02);
  c = choose(2e-3, e, e);
  CHECK(c.limits.dt == Approx(2e-3 * 1.02).epsilon(1e-9));
  CHECK(choose(2e-3, target / 100, target / 100).limits.dt == Approx(2e-3 * ChooseFlowStep::kGrow).epsilon(1e-9));
  // Above it: shrinks by at most 10% a step, and not below the depth limit.
  CHECK(choose(2e-3, 4 * target, 4 * target).limits.dt == Approx(2e-3 * ChooseFlowStep::kShrink).epsilon(1e-9));
  CHECK(choose(1.05e-3, 4 * target, 4 * target).limits.dt == depth);
  // The larger of this step's error and the smoothed one decides: a single
  // calm step amid compressed ones does not let the step grow.
  c = choose(2e-3, target / 4, 2 * target);
  const double smooth = ChooseFlowStep::kKeep * 2 * target + (1 - ChooseFlowStep::kKeep) * target / 4;
  CHECK(c.error_mean == Approx(smooth));
  CHECK(c.limits.dt == Approx(2e-3 * std::max(ChooseFlowStep::kShrink, std::sqrt(target / smooth))).epsilon(1e-9));
  // The flow CFL still caps it, and the controller's base is the step before
  // landing on an output time, not the landed one.
  CHECK(choose(2e-3, target / 4, target / 4, 1.5e-3).limits.dt == Approx(1.5e-3));
  c = choose(2e-3, target / 4, target / 4, 1.0, 2.5e-3);
  CHECK(c.limits.dt == Approx(1.25e-3));
  CHECK(c.dt_chosen == Approx(2.1e-3));
  // Landing: the time left in equal steps, as many as put the step nearest
  // dt in ratio, none more than 10% beyond dt (here the flow CFL's 1.5 ms
  // throughout). {steps' worth, steps}: 10.5 is 11 steps of 0.955 dt, not 10
  // and two halves (sqrt(10 x 11) = 10.49 divides 10 from 11); 9.4 is 9
  // steps 4.4% longer; 3.02 is 3 steps 0.7% longer; 1.087 one step 8.7%
  // longer, not two of 0.54 dt; 1.2 two steps (one would be 20% longer); 0.6
  // the time left.
  const std::pair<double, int> landings[] = {{10.5, 11}, {9.4, 9}, {3.02, 3}, {1.087, 1}, {1.2, 2}, {0.6, 1}};
  for (const auto& [steps_left, steps] : landings) {
    double remaining = steps_left * 1.5e-3, shortest = 1.0, longest = 0.0;
    int taken = 0;
    while (remaining > 1e-12 && taken < 100) {
      const double dt = choose(1.5e-3, target / 4, target / 4, 1.5e-3, remaining).limits.dt;
      shortest = std::min(shortest, dt);
      longest = std::max(longest, dt);
      remaining -= dt;
      ++taken;
    }
    INFO(steps_left << " steps' worth: " << taken << " steps of " << shortest << " to " << longest << " s");
    CHECK(taken == steps);
    CHECK(longest <= ChooseFlowStep::kLandStretch * 1.5e-3 * (1 + 1e-12));
    CHECK(shortest == Approx(longest).epsilon(1e-9));
    CHECK(std::abs(remaining) < 1e-15);
  }
  // A hard cap (run.max_dt here) is passed by 1% at most: 1.05 steps of
  // max_dt's worth land in two.
  {
    FlowControl capped{};
    capped.stats.max_speed2 = 1.0f;
    ChooseFlowStep{1.0, 0.0, 1.0e-3, 1.0e-3, 1e-8, 1.05e-3, &capped, 0.0}(0);
    CHECK(capped.limits.dt == Approx(0.525e-3));
    ChooseFlowStep{1.0, 0.0, 1.0e-3, 1.0e-3, 1e-8, 1.008e-3, &capped, 0.0}(0);
    CHECK(capped.limits.dt == Approx(1.008e-3));
  }
  // The compression a landed step left is read as that of the step chosen:
  // two half steps leave a quarter of it, which does not grow the step; a
  // step 10% longer leaves 1.21 times it, which does not shrink it.
  for (const double taken : {1.0e-3, 2.2e-3}) {
    const double e_taken = target * (taken / 2e-3) * (taken / 2e-3);
    c = choose(2e-3, e_taken, target, 1.0, 1.0, taken);
    INFO("a landed step of " << taken << " s");
    CHECK(c.error_mean == Approx(target));
    CHECK(c.limits.dt == Approx(2e-3).epsilon(1e-9));
  }
  // pbf.step_error = 0: the depth limit throughout.
  FlowControl off{};
  off.stats.max_speed2 = 1.0f;
  off.dt_chosen = 2e-3;
  ChooseFlowStep{1.0, 0.0, 1.0, depth, 1e-8, 1.0, &off, 0.0}(0);
  CHECK(off.limits.dt == depth);
}

TEST_CASE("pbf step size: a flowing liquid's steps are sized to pbf.step_error_flow, a slower one's to pbf.step_error",
          "[sph][cpu]") {
  // A compression of 0.75% left: above the target at rest (0.5%: the step
  // shrinks, by sqrt(0.005 / 0.0075) = 0.82, clamped to kShrink), below the
  // flowing one (1%: it grows, by 1.15, clamped to kGrow). The switch is the
  // largest speed against flow_speed (2 m/s here).
  const double depth = 1e-3, e = 0.0075, n = 1000;
  auto choose = [&](float speed, double flow_target) {
    FlowControl c{};
    c.stats.max_speed2 = speed * speed;
    c.stats.error_sum = e * n;
    c.stats.count = n;
    c.dt_chosen = 2e-3;
    c.error_mean = e;
    ChooseFlowStep{1.0, 0.0, 1.0, depth, 1e-8, 1.0, &c, 0.005, flow_target, 2.0}(0);
    return c.limits.dt;
  };
  CHECK(choose(1.9f, 0.01) == Approx(2e-3 * ChooseFlowStep::kShrink).epsilon(1e-9));
  CHECK(choose(2.1f, 0.01) == Approx(2e-3 * ChooseFlowStep::kGrow).epsilon(1e-9));
  CHECK(choose(2.1f, 0.0) == Approx(2e-3 * ChooseFlowStep::kShrink).epsilon(1e-9));  // 0: step_error throughout
  // The scene's keys: the flow target at least the one at rest, the speed in sqrt(g H).
  const PbfParams p = make_pbf_params(resolve_scene(pbf_scene("scenes/dam_break.json",
      {"pbf.step_error=0.02", "pbf.step_error_flow=0.01", "pbf.flow_speed=1.5"})).scene);
  CHECK(p.step_error_flow == Approx(0.02f));
  CHECK(p.flow_speed == Approx(1.5f * p.speed_floor));
}

TEST_CASE("pbf: the dam break takes fewer steps under the error-sized step, at a mean compression near its target",
          "[sph][cpu]") {
  // At this coarse spacing PBF's 5 ms cap would set every step; without it
  // the depth limit does, as at the scene's usual sizes.
  auto run = [](const std::string& step_error, double& error_mean) {
    const Scene s = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.03", "run.max_dt=0.1", "pbf.step_error=" + step_error});
    auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
    double sum = 0;
    while (solver->time() < 0.6 - 1e-12) {
      solver->step(0.6);
      sum += solver->last_solve().density_error_mean;
    }
    error_mean = sum / double(solver->steps());
    return solver->steps();
  };
  double fixed_error = 0, sized_error = 0;
  const uint64_t fixed = run("0", fixed_error), sized = run("0.005", sized_error);
  INFO("steps " << fixed << " -> " << sized << ", mean compression " << fixed_error << " -> " << sized_error);
  CHECK(double(sized) < 0.9 * double(fixed));
  CHECK(sized_error > fixed_error);
  CHECK(sized_error < 1.5 * 0.005);
}

TEST_CASE("pbf: a density tolerance ends the iterations early, on the steps of a flowing liquid only", "[sph][cpu]") {
  // pbf.tolerance ends a step's iterations after the first Lambda pass
  // whose mean error is within it, but only on a step that starts from a
  // flowing liquid (its largest speed above pbf.flow_speed: at rest the
  // iterations are the rest weights' schedule) and whose size the
  // error-sized limit does not hold (PbfSolverImpl::solve). The dam break
  // from rest to 0.5 s at a tolerance no step misses, without run.max_dt
  // (which would hold every step at 4 cm): each step takes one iteration
  // where both hold and all three where either fails, and both kinds of
  // failure occur.
  const Scene loose = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.04", "pbf.iterations=3", "pbf.tolerance=0.5", "run.max_dt=1"});
  const SolverInput in = make_solver_input(resolve_scene(loose), PresenceMode::Off);
  auto a = make_cpu_solver(in);
  int ended = 0, at_rest = 0, error_held = 0;
  while (a->time() < 0.5) {
    a->step(0.5);
    const StepLimits& l = a->last_limits();
    const bool flowing = l.max_speed > double(in.pbf.flow_speed);
    const bool may_end = flowing && l.bound != kBoundSolver;
    INFO("t = " << a->time() << ", largest speed " << l.max_speed << ", bound " << int(l.bound));
    REQUIRE(a->last_solve().iterations == (may_end ? 1 : 3));
    CHECK(a->last_solve().converged);
    ended += may_end;
    at_rest += !flowing;
    error_held += flowing && !may_end;
  }
  INFO("ended " << ended << ", at rest " << at_rest << ", flowing and held by the error-sized limit " << error_held);
  CHECK(ended > 0);
  CHECK(at_rest > 0);
  CHECK(error_held > 0);
  // Once the column falls, its bottom compresses past any tiny tolerance.
  const Scene tight = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.04", "pbf.iterations=2", "pbf.tolerance=1e-9"});
  auto b = make_cpu_solver(make_solver_input(resolve_scene(tight), PresenceMode::Off));
  for (int k = 0; k < 10; ++k) b->step(1.0);
  CHECK(b->last_solve().iterations == 2);
  CHECK_FALSE(b->last_solve().converged);
  CHECK(b->last_solve().density_error_mean > 1e-9);
}

TEST_CASE("pbf: iterations ended by the tolerance are the steps of that many iterations, bit for bit", "[sph][cpu]") {
  // The iterations end after the Lambda pass whose mean error is within
  // the tolerance, and the finishing pass applies its multipliers
  // (PbfSolverImpl::solve). So a run whose every step ends after its first
  // Lambda pass is the run of one iteration, and one whose tolerance is
  // never met the run without one. Uniform weights and no
  // depth limit: the rest weights' schedule and the depth limit depend on
  // the iteration count. The tolerance ends only the steps of a flowing
  // liquid that the error-sized limit does not hold: the block is thrown,
  // every speed above zero counts as flowing, and the steps are not sized
  // by their error.
  auto run = [](std::vector<std::string> set, std::vector<int>& iterations) {
    set.insert(set.end(), {"sph.spacing=0.04", "pbf.rest_weights=uniform", "pbf.depth_error=0", "pbf.step_error=0",
                           "pbf.flow_speed=0", "fluid.0.velocity=[1,0,0]"});
    auto solver = make_cpu_solver(make_solver_input(resolve_scene(pbf_scene("scenes/dam_break.json", set)), PresenceMode::Off));
    for (int k = 0; k < 8; ++k) {
      solver->step(1.0);
      iterations.push_back(solver->last_solve().iterations);
    }
    return solver->download();
  };
  auto same = [](const HostParticles& a, const HostParticles& b) {
    REQUIRE(a.pos.size() == b.pos.size());
    for (size_t i = 0; i < a.pos.size(); ++i) {
      REQUIRE(a.id[i] == b.id[i]);
      REQUIRE(a.pos[i].x == b.pos[i].x);
      REQUIRE(a.pos[i].y == b.pos[i].y);
      REQUIRE(a.pos[i].z == b.pos[i].z);
      REQUIRE(a.vel[i].z == b.vel[i].z);
    }
  };
  std::vector<int> ended_k, one_k, tight_k, plain_k;
  const HostParticles ended = run({"pbf.iterations=5", "pbf.tolerance=0.5"}, ended_k);
  const HostParticles one = run({"pbf.iterations=1"}, one_k);
  CHECK(ended_k == std::vector<int>(8, 1));
  CHECK(one_k == std::vector<int>(8, 1));
  same(ended, one);
  const HostParticles tight = run({"pbf.iterations=3", "pbf.tolerance=1e-9"}, tight_k);
  const HostParticles plain = run({"pbf.iterations=3"}, plain_k);
  CHECK(tight_k == std::vector<int>(8, 3));
  same(tight, plain);
}

TEST_CASE("pbf: a diverging run stops with the step named", "[sph][cpu]") {
  // A block thrown at a wall at 200 m/s with one iteration and steps of ten
  // spacings piles onto the wall: the density error runs far past 100%.
  Scene s = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.04", "pbf.iterations=1", "sph.cfl=10", "run.max_dt=0.1"});
  s.fluid[0] = {{{0.2, 0.0, 0.0}, {0.6, 0.67, 0.3}}, {-200.0, 0.0, 0.0}};
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  std::string message;
  try {
    for (int k = 0; k < 20; ++k) solver->step(100.0);
  } catch (const SimulationError& e) {
    message = e.what();
  }
  INFO(message);
  CHECK(message.find("density error diverged at step 0") != std::string::npos);
}

TEST_CASE("pbf vorticity: a rigid rotation has omega = 2 Omega inside, and confinement pushes along N x omega",
          "[sph][cpu]") {
  // A lattice turning about z at Omega: the curl of v = Omega x x is 2 Omega.
  const Scene s = pbf_scene("scenes/dam_break.json", {"sph.spacing=0.02", "pbf.vorticity=1"});
  const ResolvedScene r = resolve_scene(s);
  const double dx = s.sph.spacing;
  const Vec3f omega_rigid = {0.0f, 0.0f, 3.0f};
  std::vector<Vec3f> pts;
  for (int z = 0; z < 12; ++z)
    for (int y = 0; y < 12; ++y)
      for (int x = 0; x < 12; ++x) pts.push_back({float(0.2 + x * dx), float(0.1 + y * dx), float(0.1 + z * dx)});
  const GridGeom& g = r.size.grid;
  const GridBuild gb = build_grid(Backend::Cpu, g, pts);
  const size_t n = pts.size();
  std::vector<Float4> pos(n), vel(n), omega(n);
  const Vec3f centre = {float(0.2 + 5.5 * dx), float(0.1 + 5.5 * dx), 0.0f};
  for (size_t k = 0; k < n; ++k) {
    const Vec3f p = pts[gb.order[k]], v = cross(omega_rigid, p - centre);
    pos[k] = {p.x, p.y, p.z, 1000.0f};
    vel[k] = {v.x, v.y, v.z, 0.0f};
  }
  std::vector<uint32_t> count(n, 1u);  // every mask "overflowed": the direct loop
  const PairMask none{nullptr, count.data(), uint32_t(n), 0u};

  for (uint32_t i = 0; i < n; ++i)
    Vorticity<true>{r.pbf, g, gb.fine_offsets.data(), none, pos.data(), vel.data(), omega.data()}(i);
  // The discrete curl of a rigid rotation inside a full lattice, in double:
  // 2 Omega times M = sum_j V (-dW/dr / r) x_j^2 (about, not exactly, 1 with
  // the spiky gradient and poly6's lattice volume).
  const PbfKernel<double> kd = PbfKernel<double>::make(r.pbf.kernel.s);
  double moment = 0;
  for (int z = -3; z <= 3; ++z)
    for (int y = -3; y <= 3; ++y)
      for (int x = -3; x <= 3; ++x) {
        const double rr = dx * std::sqrt(double(x * x + y * y + z * z));
        moment += double(r.pbf.volume) * -kd.dW_over_r(rr) * (x * dx) * (x * dx);
      }
  const double expected = 2 * omega_rigid.z * moment;
  INFO("expected omega " << expected << " (moment " << moment << ")");
  size_t inner = 0;
  for (size_t k = 0; k < n; ++k) {
    const Vec3f p = xyz(pos[k]);
    const double margin = std::min({p.x - 0.2, p.y - 0.1, p.z - 0.1, 0.2 + 11 * dx - p.x, 0.1 + 11 * dx - p.y,
                                    0.1 + 11 * dx - p.z});
    if (margin <= r.pbf.kernel.s) continue;
    ++inner;
    CHECK(std::abs(omega[k].z - expected) < 1e-3 * expected);
    CHECK(std::abs(omega[k].x) < 1e-3);
    CHECK(std::abs(omega[k].y) < 1e-3);
  }
  CHECK(inner > 0);
  // Confinement: omega larger at the centre than outside it (set here), so
  // N points inward and the force N x omega is tangential, along the rotation.
  for (size_t k = 0; k < n; ++k) {
    const Vec3f p = xyz(pos[k]);
    const float rr = std::sqrt(length2(Vec3f{p.x - centre.x, p.y - centre.y, 0.0f}));
    omega[k] = {0.0f, 0.0f, 1.0f / (1.0f + 10.0f * rr), 1.0f / (1.0f + 10.0f * rr)};
  }
  FlowControl control{};
  control.limits.dt = 1e-3;
  std::vector<Float4> vel2(n, Float4{0, 0, 0, 0});
  for (uint32_t i = 0; i < n; ++i)
    Confine<true>{r.pbf, g, gb.fine_offsets.data(), none, &control, pos.data(), omega.data(), vel2.data()}(i);
  size_t along = 0, checked = 0;
  for (size_t k = 0; k < n; ++k) {
    const Vec3f p = xyz(pos[k]), d = {p.x - centre.x, p.y - centre.y, 0.0f};
    if (length2(d) < dx * dx) continue;
    ++checked;
    along += dot(cross(Vec3f{0, 0, 1}, d), xyz(vel2[k])) > 0 ? 1 : 0;  // counter-clockwise, as omega
  }
  CHECK(along > 0.9 * checked);
}

TEST_CASE("pbf scene options: refused by name where they do not apply or are out of range", "[scene][cpu]") {
  const std::string base = R"({"tank": {"min": [0,0,0], "max": [1,1,1]}, "fluid": [{"min": [0,0,0], "max": [0.5,0.5,0.5]}], )";
  auto error_of = [&](const std::string& rest) { return test::scene_error(base + rest); };
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "sph"}})").find("\"wcsph\", \"pbf\"") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf", "speed_of_sound": 20}})").find("sph.speed_of_sound") !=
        std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1}, "pbf": {"iterations": 4}})").find("pbf") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"iterations": 0}})").find("pbf.iterations") !=
        std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"relaxation": 0}})").find("pbf.relaxation") !=
        std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf", "cfl": 0}})").find("sph.cfl") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"step_error": -0.01}})").find("pbf.step_error") !=
        std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"wall_margin": 0.6}})").find("pbf.wall_margin") !=
        std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"images": "moving"}})").find("pbf.images") !=
        std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"images": "static"}})").empty());
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"rest_weights": "chebychev"}})")
            .find("pbf.rest_weights") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"rest_weights": "uniform"}})").empty());
  // s_corr that would throw a free surface off: W(dq) = 0 at the support,
  // a flat falloff (n = 1) at full strength, a wide support's many close
  // neighbours; full strength at the default dq and n is allowed.
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"scorr_k": 1, "scorr_dq": 1}})")
            .find("pbf.scorr_dq = 1: makes s_corr push a flat free surface by inf") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"scorr_k": 1, "scorr_n": 1}})")
            .find("pbf.scorr_n") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"scorr_k": 0.1, "support": 4}})")
            .find("pbf.scorr_k") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"scorr_k": 1}})").empty());
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"scorr_k": 0, "scorr_dq": 1}})").empty());
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "run": {"min_dt": 0.01, "max_dt": 0.001}})")
            .find("run.max_dt") != std::string::npos);
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "pbf": {"iterations": 4}})").empty());
  // Defaults that depend on the solver.
  const Scene p = parse_scene(base + R"("sph": {"spacing": 0.1, "solver": "pbf"}})", "s.json");
  CHECK(p.sph.cfl == SphConfig::kPbfCfl);
  CHECK(p.run.max_dt == Scene::Run::kFlowMaxDt);
  CHECK(p.sph.wall_layers() == 0);
  CHECK(p.sph.pbf.mirrored_images);
  CHECK(p.sph.pbf.rest_chebyshev);
  const Scene w = parse_scene(base + R"("sph": {"spacing": 0.1}})", "s.json");
  CHECK(w.sph.cfl == SphConfig::kWcsphCfl);
}

// The issue's criterion is a largest speed below 1% of sqrt(g H) after 0.2 s;
// PBF with a few Jacobi iterations does not reach it: the column's
// compression mode rings after the release, a few percent of sqrt(g H) for
// a few tenths of a second, and single particles of the bulk move at 1-3%
// as its packing settles (docs/validation.md has the measurements). What is
// asserted: the column stays put and compressed under 1% on average, and
// with the rest weights (pbf.rest_weights, the default) no speed beyond
// 0.15 sqrt(g H) (measured: 0.09, in the ringing just after 0.2 s); with
// lambda as is in every iteration the Jacobi overshoot keeps single
// particles at a quarter of it (measured: 0.25).
TEST_CASE("pbf: a column at rest stays at rest (1 s, 40 layers)", "[sph][slow][cpu]") {
  const std::string weights = GENERATE(as<std::string>(), "chebyshev", "uniform");
  Scene s = load_scene(test::source_path("scenes/stress/tall_column.json"),
                       {"sph.solver=pbf", "run.end_time=1.0", "pbf.rest_weights=" + weights});
  s.fluid[0].box.max.x = s.tank.max.x;  // a pool 0.4 m deep across the tank: no collapse, only settling
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const double H = s.fluid[0].box.max.z - s.fluid[0].box.min.z, v_ref = std::sqrt(9.81 * H);
  double worst = 0, error_sum = 0;
  int steps = 0;
  while (solver->time() < 1.0 - 1e-12) {
    solver->step(1.0);
    if (solver->time() <= 0.2) continue;
    worst = std::max(worst, solver->last_limits().max_speed);
    error_sum += solver->last_solve().density_error_mean;
    ++steps;
  }
  const HostParticles p = solver->download();
  double top = 0;
  for (const Vec3f& x : p.pos) top = std::max(top, double(x.z));
  INFO(weights << ": largest speed after 0.2 s " << worst / v_ref << " sqrt(g H), mean density error "
                << error_sum / steps << ", top " << top);
  CHECK(worst < (weights == "chebyshev" ? 0.15 : 0.5) * v_ref);
  if (weights == "uniform") CHECK(worst > 0.2 * v_ref);  // what the rest weights remove
  CHECK(error_sum / steps < 0.01);
  CHECK(std::abs(top - H) < 2 * s.sph.spacing);
}

// Output times a little more than a step apart: each frame is one step,
// 6% longer than the one chosen (ChooseFlowStep lands in the count of steps
// nearest dt and reads the compression as that of dt). With the compression
// read as it comes and each frame split into the fewest steps of at most
// 1.01 dt, the frames alternate between one step and two halves, each half
// step turning the compression the long one left into speed, and this pool
// reaches 0.29 sqrt(g H) (docs/notebook/benchmarks-history.md, "Landing on
// output times").
TEST_CASE("pbf: frames a little longer than the step take one step each, and a pool at rest stays at rest",
          "[sph][cpu]") {
  Scene s = load_scene(test::source_path("scenes/stress/tall_column.json"), {"sph.solver=pbf"});
  s.tank.max.x = 0.1;  // a pool 0.4 m deep, 10 x 4 x 40 particles
  s.fluid[0].box.max.x = s.tank.max.x;
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const double H = s.fluid[0].box.max.z - s.fluid[0].box.min.z, v_ref = std::sqrt(9.81 * H);
  solver->step(1.0);  // no output time within reach: the step chosen (the depth limit at rest)
  const double interval = 1.06 * solver->last_limits().dt;
  double worst = 0;
  int frames = 0, changes = 0, last_steps = -1;
  for (double until = solver->time() + interval; until < 0.6; until += interval) {
    int steps = 0;
    while (solver->time() < until - 1e-12) {
      solver->step(until);
      ++steps;
      if (solver->time() > 0.2) worst = std::max(worst, solver->last_limits().max_speed);
    }
    if (solver->time() > 0.1) {
      ++frames;
      changes += last_steps >= 0 && steps != last_steps;
      last_steps = steps;
    }
  }
  INFO(frames << " frames after 0.1 s, the last of " << last_steps << " steps; " << changes
              << " changes of the count; largest speed after 0.2 s " << worst / v_ref << " sqrt(g H)");
  CHECK(last_steps == 1);
  CHECK(changes == 0);
  CHECK(worst < 0.15 * v_ref);
}

TEST_CASE("pbf: the last correction in the finishing pass moves the particles as Correct does", "[sph][cpu]") {
  // The first step of a column released at rest, with and without a box far
  // from the liquid: a scene with obstacles runs Correct, the stop and
  // Finish; one without runs the last correction in the finishing pass
  // (CorrectFinish), whose XSPH smooths the velocities before that correction.
  const std::string liquid = R"({"tank": {"min": [0, 0, 0], "max": [0.6, 0.2, 0.4]},
    "fluid": [{"min": [0, 0, 0], "max": [0.15, 0.2, 0.3]}], "sph": {"spacing": 0.01, "solver": "pbf"},
    "run": {"end_time": 1, "output_interval": 0.1})";
  const Scene plain = parse_scene(liquid + "}", "plain.json");
  const Scene boxed = parse_scene(liquid + R"(, "obstacles": [{"mesh": ")" + test::source_path("scenes/meshes/unit_box.obj") +
                                      R"(", "scale": 0.05, "translate": [0.5, 0.1, 0.3]}]})",
                                  "boxed.json");
  std::vector<Vec3f> pos[2], vel[2];
  double dt[2];
  int k = 0;
  for (const Scene* s : {&plain, &boxed}) {
    auto solver = make_cpu_solver(make_solver_input(resolve_scene(*s), PresenceMode::Off));
    solver->step(1.0);
    dt[k] = solver->time();
    const HostParticles h = solver->download();
    pos[k].resize(h.id.size());
    vel[k].resize(h.id.size());
    for (size_t i = 0; i < h.id.size(); ++i) {
      pos[k][h.id[i]] = h.pos[i];
      vel[k][h.id[i]] = h.vel[i];
    }
    ++k;
  }
  REQUIRE(pos[0].size() == pos[1].size());
  CHECK(dt[0] == dt[1]);
  // The same corrections; the velocities differ by XSPH's lag only, a share
  // of the last correction's own velocity.
  double worst_x = 0, worst_dv = 0, speed = 0, mean_dv = 0, mean_speed = 0;
  for (size_t i = 0; i < pos[0].size(); ++i) {
    worst_x = std::max(worst_x, double(length(pos[0][i] - pos[1][i])));
    worst_dv = std::max(worst_dv, double(length(vel[0][i] - vel[1][i])));
    speed = std::max(speed, double(length(vel[1][i])));
    mean_dv += length(vel[0][i] - vel[1][i]) / double(pos[0].size());
    mean_speed += length(vel[1][i]) / double(pos[0].size());
  }
  INFO("positions within " << worst_x << " m, velocities within " << worst_dv << " m/s of a largest " << speed
                           << " (mean " << mean_dv << " of " << mean_speed << ")");
  CHECK(worst_x < 1e-7);
  CHECK(worst_dv > 0.0);  // the fused pass ran
  // At release the corrections make much of the velocities, so the lag shows
  // most there: 0.5% of the mean speed, 5% of the largest where the column
  // presses on the floor (measured).
  CHECK(mean_dv < 0.02 * mean_speed);
  CHECK(worst_dv < 0.1 * speed);
}
