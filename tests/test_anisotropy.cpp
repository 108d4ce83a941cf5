// Anisotropic kernels (field/anisotropy.h) and the surface error metrics
// (io/surface_error.h) against independent references: the covariance pass
// against a double brute-force computation with another eigensolver, the
// anisotropic naive field against a double sum over the reference ellipsoids,
// the presence builder's classification against naive's, the metrics on
// analytic fields, and the surface claim itself on a pool, a ball and a sheet.
#include <algorithm>
#include <cmath>
#include <random>
#include <type_traits>
#include <vector>

#include <Eigen/Eigenvalues>

#include "bench/surface.h"
#include "catch.h"
#include "helpers.h"
#include "host_particles.h"
#include "field/builders.h"
#include "field/field.h"
#include "io/metrics.h"
#include "io/surface_error.h"

using namespace sphray;

namespace {

// The small tank of test_field (dx = 0.01, cells of 0.04 m: a voxel is one spacing at refine 2).
Scene aniso_scene(const std::vector<std::string>& sets = {}) {
  std::vector<std::string> all = {"field.kernel=anisotropic"};
  all.insert(all.end(), sets.begin(), sets.end());
  const std::string text = R"({"tank": {"min": [0,0,0], "max": [0.4,0.2,0.3]},
    "fluid": [{"min": [0,0,0], "max": [0.12,0.2,0.2]}],
    "sph": {"spacing": 0.01}, "field": {"refine": 2}, "run": {"end_time": 1}})";
  return parse_scene(text, "aniso.json", all);
}

// A block of lattice points (spacing dx, jittered by `jitter` dx) filling
// [lo, hi), plus `loose` random points in the tank above it: surfaces, edges,
// corners and lone particles.
std::vector<Vec3f> liquid(const Scene& s, double jitter, int loose, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  const double dx = s.sph.spacing;
  std::vector<Vec3f> pts;
  for (int k = 0; k < 8; ++k)
    for (int j = 0; j < 12; ++j)
      for (int i = 0; i < 14; ++i)
        pts.push_back({float((i + 3.5 + jitter * u(rng)) * dx), float((j + 3.5 + jitter * u(rng)) * dx),
                       float((k + 0.5 + jitter * u(rng)) * dx)});
  std::uniform_real_distribution<double> ux(0.02, 0.38), uy(0.02, 0.18), uz(0.12, 0.28);
  for (int k = 0; k < loose; ++k) pts.push_back({float(ux(rng)), float(uy(rng)), float(uz(rng))});
  return pts;
}

// The points whose offsets from x the covariance of x sums, in double: every
// point (x's own included) and, with mirroring walls (FieldWalls), their
// images across each subset of the walls within r of x (test::HandMirrors).
std::vector<Eigen::Vector3d> seen_from(const std::vector<Vec3f>& pts, const Eigen::Vector3d& x, const FieldWalls& walls,
                                       double r) {
  const double at[3] = {x(0), x(1), x(2)};
  const test::HandMirrors mirrors(walls, r, at);
  std::vector<Eigen::Vector3d> out;
  for (const Vec3f& p : pts) mirrors.each(p, [&](const double q[3]) { out.emplace_back(q[0], q[1], q[2]); });
  return out;
}

// The kernel of point i, in double from its definition (field/anisotropy.h),
// with Eigen's iterative (QR) eigensolver instead of the closed form.
struct RefKernel {
  Eigen::Vector3d centre;  // voxels
  Eigen::Matrix3d A;
};
RefKernel reference_kernel(const std::vector<Vec3f>& pts, size_t i, const FieldSetup& fs) {
  const AnisotropyParams& ap = fs.aniso;
  const double r = ap.radius;
  const Eigen::Vector3d xi(pts[i].x, pts[i].y, pts[i].z);
  double W = 0;
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  uint32_t count = 0;
  for (const Eigen::Vector3d& p : seen_from(pts, xi, ap.walls, r)) {
    const Eigen::Vector3d d = (p - xi) / r;
    const double q = d.norm();
    if (q >= 1.0) continue;
    const double w = 1.0 - q * q * q;
    W += w;
    m += w * d;
    S += w * d * d.transpose();
    count += q > 0;  // every point but i itself
  }
  m /= W;
  const Eigen::Matrix3d C = S / W - m * m.transpose();
  Eigen::Vector3d s(1, 1, 1);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  if (count >= ap.min_neighbours && ap.stretch > 1) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(C);
    const Eigen::Vector3d l = es.eigenvalues();
    const double top = std::sqrt(std::max(l(2), 0.0));
    for (int k = 0; k < 3; ++k) s(k) = std::max(std::sqrt(std::max(l(k), 0.0)), top / ap.stretch);
    s /= std::cbrt(s(0) * s(1) * s(2));
    R = es.eigenvectors();
  }
  RefKernel k;
  k.A = R * s.cwiseInverse().cwiseAbs2().asDiagonal() * R.transpose();
  const Eigen::Vector3d c = xi + ap.smoothing * r * m;
  k.centre = Eigen::Vector3d((c(0) - fs.geom.origin.x) / fs.geom.voxel, (c(1) - fs.geom.origin.y) / fs.geom.voxel,
                             (c(2) - fs.geom.origin.z) / fs.geom.voxel);
  return k;
}

// The covariance pass run on the host over a sorted particle set: the kernels in sorted order.
std::vector<Ellipsoid> kernels_of(const HostParticleSet& ps, const FieldSetup& fs) {
  const uint32_t n = uint32_t(ps.pos.size());
  std::vector<Float4> out(3 * size_t(n));
  const ComputeAnisotropy pass{ps.grid, ps.fine_offsets.data(), ps.pos.data(), nullptr, n, fs.geom, fs.aniso, out.data()};
  for (uint32_t i = 0; i < n; ++i) pass(i);
  std::vector<Ellipsoid> e(n);
  for (uint32_t i = 0; i < n; ++i) e[i] = Ellipsoid::load(out.data(), n, i);
  return e;
}

std::vector<Vec3f> sorted_points(const HostParticleSet& ps) {
  std::vector<Vec3f> p;
  for (const Float4& q : ps.pos) p.push_back({q.x, q.y, q.z});
  return p;
}

Eigen::Matrix3d form_of(const Ellipsoid& e) {
  Eigen::Matrix3d A;
  A << e.axx, e.axy, e.axz, e.axy, e.ayy, e.ayz, e.axz, e.ayz, e.azz;
  return A;
}

}  // namespace

TEST_CASE("anisotropic kernels equal a double brute-force covariance with another eigensolver", "[field]") {
  // With the tank's walls as mirrors (the default) and without.
  const bool mirrored = GENERATE(true, false);
  const Scene s = aniso_scene({std::string("field.anisotropy.mirror_walls=") + (mirrored ? "true" : "false")});
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  REQUIRE(fs.kernel == FieldKernel::Anisotropic);
  REQUIRE(fs.aniso.walls.mirror == mirrored);
  // Sorted by the scene's grid (cells of 4 spacings, wider than the radius
  // of 3) and by the pass's own (cells of half the radius, rows two cells out).
  const GridGeom scene_grid = measure_scene(s).grid;
  const GridGeom pass_grid = anisotropy_grid(scene_grid, fs.aniso.radius);
  REQUIRE(pass_grid.cell_size < 0.5f * scene_grid.cell_size);
  const GridGeom grid = GENERATE_COPY(scene_grid, pass_grid);
  INFO("cells of " << grid.cell_size / s.sph.spacing << " spacings" << (mirrored ? ", walls mirrored" : ""));
  const HostParticleSet ps(grid, liquid(s, 0.3, 300, 5));
  const std::vector<Vec3f> pts = sorted_points(ps);
  const std::vector<Ellipsoid> e = kernels_of(ps, fs);
  double worst_form = 0, worst_centre = 0, worst_half = 0;
  size_t near_walls = 0;  // particles within the radius of a wall: the block's bottom layer, some loose ones
  for (const Vec3f& p : pts)
    near_walls += std::min({p.x - s.tank.min.x, s.tank.max.x - p.x, p.y - s.tank.min.y, s.tank.max.y - p.y,
                            p.z - s.tank.min.z, s.tank.max.z - p.z}) < fs.aniso.radius;
  CHECK(near_walls > 150);
  for (size_t i = 0; i < pts.size(); ++i) {
    const RefKernel r = reference_kernel(pts, i, fs);
    worst_form = std::max(worst_form, (form_of(e[i]) - r.A).norm() / r.A.norm());
    worst_centre = std::max(worst_centre, (Eigen::Vector3d(e[i].centre.x, e[i].centre.y, e[i].centre.z) - r.centre).norm());
    // The box of the unit ellipsoid: sqrt of the diagonal of A's inverse.
    const Eigen::Matrix3d M = r.A.inverse();
    worst_half = std::max({worst_half, std::abs(e[i].half.x - std::sqrt(M(0, 0))), std::abs(e[i].half.y - std::sqrt(M(1, 1))),
                           std::abs(e[i].half.z - std::sqrt(M(2, 2)))});
  }
  INFO("worst relative form error " << worst_form << ", centre " << worst_centre << " voxels, half-extent " << worst_half);
  CHECK(worst_form < 2e-3);
  CHECK(worst_centre < 1e-4);
  CHECK(worst_half < 2e-3);
}

TEST_CASE("WCSPH's pair loop sums the anisotropic covariance of a double brute force, and the field uses it",
          "[field][sph]") {
  // With the tank's walls as mirrors (the default: the block lies against
  // four walls) and without.
  const bool mirrored = GENERATE(true, false);
  const Scene s = aniso_scene({"fluid.0.velocity=[0.3,0,-0.2]",
                               std::string("field.anisotropy.mirror_walls=") + (mirrored ? "true" : "false")});
  const ResolvedScene r = resolve_scene(s);
  const FieldSetup fs = make_field_setup(r);
  const SolverInput in = make_solver_input(r, PresenceMode::AtUntil);
  REQUIRE(in.covariance_radius == fs.aniso.radius);  // 3 spacings: within WCSPH's support of 4
  REQUIRE(in.covariance_mirror_walls == mirrored);
  auto solver = make_cpu_solver(in);
  for (int k = 0; k < 20; ++k) solver->step(1.0);  // presence (and with it the sums) off: not reaching 1 s
  CHECK_FALSE(solver->view().covariance);
  const HostParticles before = solver->download();
  solver->step(solver->time() + 1e-4);  // reaches its time: the loop sums them, at the positions of `before`
  const ParticleView pv = solver->view();
  REQUIRE(pv.covariance);
  CHECK(pv.covariance_radius == fs.aniso.radius);
  CHECK(pv.covariance_mirror_walls == mirrored);
  const HostParticles after = solver->download();
  REQUIRE(after.id.size() == before.id.size());
  std::vector<size_t> where(before.id.size());
  for (size_t k = 0; k < before.id.size(); ++k) where[before.id[k]] = k;
  std::vector<Vec3f> start(after.id.size());  // the step's start positions, in the view's order
  for (size_t i = 0; i < after.id.size(); ++i) start[i] = before.pos[where[after.id[i]]];

  // The sums against double ones over every particle at the step's start.
  const double radius = fs.aniso.radius;
  double worst = 0, worst_count = 0;
  for (size_t i = 0; i < start.size(); ++i) {
    double ref[11] = {1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    const Eigen::Vector3d xi(start[i].x, start[i].y, start[i].z);
    for (const Eigen::Vector3d& p : seen_from(start, xi, fs.aniso.walls, radius)) {
      const double d[3] = {(p(0) - xi(0)) / radius, (p(1) - xi(1)) / radius, (p(2) - xi(2)) / radius};
      const double q2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
      if (q2 >= 1 || q2 == 0) continue;  // i itself is the 1 of W
      const double w = 1 - q2 * std::sqrt(q2);
      const double add[11] = {w, w * d[0], w * d[1], w * d[2], w * d[0] * d[0], w * d[1] * d[1],
                              w * d[2] * d[2], w * d[0] * d[1], w * d[0] * d[2], w * d[1] * d[2], 1};
      for (int k = 0; k < 11; ++k) ref[k] += add[k];
    }
    const CovarianceSums c = CovarianceSums::load(pv.covariance, pv.n, uint32_t(i));
    const double got[11] = {c.w, c.mx, c.my, c.mz, c.sxx, c.syy, c.szz, c.sxy, c.sxz, c.syz, c.count};
    for (int k = 0; k < 10; ++k) worst = std::max(worst, std::abs(got[k] - ref[k]) / ref[0]);
    worst_count = std::max(worst_count, std::abs(got[10] - ref[10]));
  }
  INFO("worst difference of a sum, relative to W: " << worst << "; of a count: " << worst_count);
  CHECK(worst < 1e-5);
  CHECK(worst_count == 0);

  // Their kernels: the reference's shape at the start, centred from where the particle is now.
  double worst_form = 0, worst_centre = 0;
  std::vector<Float4> ell(3 * size_t(pv.n));
  const AnisotropyFromSums from{pv.pos, pv.covariance, pv.n, fs.geom, fs.aniso, ell.data()};
  for (uint32_t i = 0; i < pv.n; ++i) {
    from(i);
    const Ellipsoid e = Ellipsoid::load(ell.data(), pv.n, i);
    const RefKernel k = reference_kernel(start, i, fs);
    const Vec3f moved = (xyz(pv.pos[i]) - start[i]) * (1.0f / fs.geom.voxel);
    worst_form = std::max(worst_form, (form_of(e) - k.A).norm() / k.A.norm());
    worst_centre = std::max(worst_centre, (Eigen::Vector3d(e.centre.x - moved.x, e.centre.y - moved.y,
                                                           e.centre.z - moved.z) - k.centre).norm());
  }
  INFO("worst relative form error " << worst_form << ", centre " << worst_centre << " voxels");
  CHECK(worst_form < 2e-3);
  CHECK(worst_centre < 1e-4);

  // The builder takes them: its field differs from the one of its own pass
  // (at the positions after the step) by that step's motion only (near a
  // wall an image moves against its original: up to twice that motion).
  const std::vector<float> with_sums = test::cpu_field(fs, pv, FieldKind::Naive);
  ParticleView own = pv;
  own.covariance = nullptr;
  const std::vector<float> with_pass = test::cpu_field(fs, own, FieldKind::Naive);
  double differ = 0;
  for (size_t v = 0; v < with_sums.size(); ++v) differ = std::max(differ, double(std::abs(with_sums[v] - with_pass[v])));
  INFO("largest difference of the two fields " << differ << " (iso " << fs.shape.iso << ")");
  CHECK(differ > 0);
  CHECK(differ < (mirrored ? 0.03 : 0.015) * fs.shape.iso);
  // Sums made for the other wall setting are not taken: the builder runs its
  // own pass (the same field to the order of the splat's adds, which the
  // host's threads vary).
  ParticleView other = pv;
  other.covariance_mirror_walls = !mirrored;
  const std::vector<float> with_other = test::cpu_field(fs, other, FieldKind::Naive);
  double rerun = 0;
  for (size_t v = 0; v < with_pass.size(); ++v)
    rerun = std::max(rerun, std::abs(double(with_other[v]) - with_pass[v]) / (1.0 + with_pass[v]));
  INFO("the own pass again, from sums of the other setting: largest relative difference " << rerun);
  CHECK(rerun < 1e-5);
  CHECK(rerun < 1e-3 * differ);
}

TEST_CASE("anisotropic kernels: spheres inside and alone, flat at a surface, stretch and volume as set", "[field]") {
  const Scene s = aniso_scene();
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  const HostParticleSet ps(measure_scene(s).grid, liquid(s, 0.0, 0, 1));
  const std::vector<Vec3f> pts = sorted_points(ps);
  const std::vector<Ellipsoid> e = kernels_of(ps, fs);
  const double dx = s.sph.spacing;
  int interior = 0, surface = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Matrix3d A = form_of(e[i]);
    CHECK(A.determinant() == Approx(1.0).epsilon(1e-4));  // volume kept
    const Eigen::Vector3d l = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(A).eigenvalues();
    CHECK(std::sqrt(l(2) / l(0)) <= fs.aniso.stretch * (1 + 1e-4));  // axis ratio within the limit
    const double x = pts[i].x / dx, y = pts[i].y / dx, z = pts[i].z / dx;
    const bool deep = x > 6 && x < 14 && y > 6 && y < 12 && z > 3 && z < 5;
    const bool top = z > 7 && x > 6 && x < 14 && y > 6 && y < 12;
    if (deep) {  // surrounded evenly: a sphere where it was
      ++interior;
      CHECK((A - Eigen::Matrix3d::Identity()).norm() < 1e-3);
      const Vec3f u = fs.geom.to_voxels(pts[i]);
      CHECK(std::abs(e[i].centre.x - u.x) + std::abs(e[i].centre.y - u.y) + std::abs(e[i].centre.z - u.z) < 1e-3);
    }
    if (top) {  // the free surface: thin along z, wide along x and y, centre pulled inward
      ++surface;
      CHECK(A(2, 2) > 1.5);
      CHECK(A(0, 0) < 1.0);
      CHECK(A(1, 1) < 1.0);
      CHECK(std::abs(A(0, 2)) + std::abs(A(1, 2)) < 1e-3);
      CHECK(e[i].centre.z < fs.geom.to_voxels(pts[i]).z);
    }
  }
  CHECK(interior > 10);
  CHECK(surface > 10);
  // A lone particle, and every particle with stretch 1, is a sphere.
  const HostParticleSet lone(measure_scene(s).grid, {Vec3f{0.2f, 0.1f, 0.2f}});
  CHECK((form_of(kernels_of(lone, fs)[0]) - Eigen::Matrix3d::Identity()).norm() < 1e-6);
  const FieldSetup round = make_field_setup(resolve_scene(aniso_scene({"field.anisotropy.stretch=1"})));
  for (const Ellipsoid& k : kernels_of(ps, round)) REQUIRE((form_of(k) - Eigen::Matrix3d::Identity()).norm() < 1e-6);
}

TEST_CASE("anisotropic naive field equals a double sum over the reference ellipsoids", "[field]") {
  // The builder sorts the particles by the pass's own grid: also where the
  // radius (4 spacings) is wider than the solver's grid cell (a support of 3).
  const bool wide = GENERATE(false, true);
  const Scene s = wide ? aniso_scene({"field.anisotropy.radius=4", "sph.smoothing_ratio=1.5"}) : aniso_scene();
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  if (wide) REQUIRE(fs.aniso.radius > measure_scene(s).grid.cell_size);
  const HostParticleSet ps(measure_scene(s).grid, liquid(s, 0.3, 200, 9));
  const std::vector<Vec3f> pts = sorted_points(ps);
  std::vector<RefKernel> ref;
  for (size_t i = 0; i < pts.size(); ++i) ref.push_back(reference_kernel(pts, i, fs));
  const std::vector<float> naive = test::cpu_field(fs, ps.view(), FieldKind::Naive);
  const double R = fs.shape.radius, c2 = fs.shape.core2;
  double worst = 0;
  std::mt19937 rng(2);
  int inside = 0;
  for (int t = 0; t < 3000; ++t) {
    // Half the samples near the liquid block, where the ellipsoids overlap.
    const int i = t % 2 ? int(rng() % 24) : int(rng() % fs.geom.nx), j = int(rng() % fs.geom.ny),
              k = t % 2 ? int(rng() % 16) : int(rng() % fs.geom.nz);
    double sum = 0;
    for (const RefKernel& r : ref) {
      const Eigen::Vector3d d = Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) - r.centre;
      const double q2 = d.dot(r.A * d);
      if (q2 < R * R) sum += 1.0 / (q2 + c2) - 1.0 / (R * R + c2);
    }
    const float got = naive[fs.geom.index(i, j, k)];
    inside += got >= fs.shape.iso;
    worst = std::max(worst, std::abs(got - sum) / (1.0 + sum));
  }
  INFO("worst relative error " << worst << ", " << inside << " samples inside");
  CHECK(inside > 200);
  CHECK(worst < 1e-3);
}

TEST_CASE("presence builder with ellipsoids and without presence classifies exactly as naive", "[field]") {
  for (int refine : {0, 1, 2}) {
    INFO("refine " << refine);
    const Scene s = aniso_scene({"field.refine=" + std::to_string(refine)});
    const FieldSetup fs = make_field_setup(resolve_scene(s));
    CHECK(fs.mark_occupied);
    // Random points: no cell is full, so every inside voxel is the splat's or a marked one.
    std::mt19937 rng(17 + refine);
    std::uniform_real_distribution<float> ux(0.0f, 0.4f), uy(0.0f, 0.2f), uz(0.0f, 0.3f);
    std::vector<Vec3f> pts(4000);
    for (auto& p : pts) p = {ux(rng), uy(rng), uz(rng)};
    const HostParticleSet ps(measure_scene(s).grid, pts);
    const std::vector<float> naive = test::cpu_field(fs, ps.view(), FieldKind::Naive);
    const std::vector<float> pres = test::cpu_field(fs, ps.view(), FieldKind::Presence);
    size_t differ = 0, inside = 0;
    for (size_t v = 0; v < naive.size(); ++v) {
      differ += (naive[v] >= fs.shape.iso) != (pres[v] >= fs.shape.iso);
      inside += naive[v] >= fs.shape.iso;
    }
    CHECK(inside > 500);
    CHECK(differ == 0);
    CHECK(*std::max_element(pres.begin(), pres.end()) <= fs.shape.clip * (1.0f + 1e-6f));
  }
}

// Presence for a lattice block of nx x ny x nz points: toward each side, the
// layers of liquid beyond the point over 4 (at most 1), [6][n] as the solvers
// write it (+x, -x, +y, -y, +z, -z).
std::vector<float> block_presence(int nx, int ny, int nz) {
  const size_t n = size_t(nx) * ny * nz;
  std::vector<float> p(6 * n);
  size_t q = 0;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i, ++q) {
        const int beyond[6] = {nx - 1 - i, i, ny - 1 - j, j, nz - 1 - k, k};
        for (int d = 0; d < 6; ++d) p[d * n + q] = std::min(1.0f, float(beyond[d]) / 4.0f);
      }
  return p;
}

TEST_CASE("the anisotropy pass's own grid finds the same neighbours among far fewer candidates", "[field]") {
  // Under PBF the view's cells are two supports wide (4.2 spacings): a
  // jittered block of liquid, its particles at least the radius from its
  // faces, sorted by that grid and by the pass's.
  const Scene s = aniso_scene({"sph.solver=pbf", "tank.max=[0.4,0.4,0.4]"});
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  const GridGeom view = measure_scene(s).grid;
  REQUIRE(view.cell_size / s.sph.spacing == Approx(4.2).epsilon(1e-3));
  std::vector<Vec3f> pts;
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> jit(-0.15, 0.15);
  const int m = 24;
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m; ++i)
        pts.push_back({float((i + 4.3 + jit(rng)) * 0.01), float((j + 4.3 + jit(rng)) * 0.01), float((k + 4.3 + jit(rng)) * 0.01)});
  const float r = fs.aniso.radius, lo = 0.043f + r, hi = 0.043f + (m - 1) * 0.01f - r;
  auto inner = [&](const Float4& p) { return p.x > lo && p.x < hi && p.y > lo && p.y < hi && p.z > lo && p.z < hi; };
  struct Count { double candidates = 0, neighbours = 0; size_t queries = 0; };
  auto count = [&](const GridGeom& g, auto span) {
    constexpr int S = decltype(span)::value;
    const HostParticleSet ps(g, pts);
    Count c;
    for (const Float4& q : ps.pos) {
      if (!inner(q)) continue;
      ++c.queries;
      for (int row = 0; row < candidate_rows<S>(); ++row) {
        uint32_t b = 0, e = 0;
        if (!candidate_row<S>(g, ps.fine_offsets.data(), xyz(q), row, b, e, r)) continue;
        c.candidates += e - b;
        for (uint32_t j = b; j < e; ++j) c.neighbours += length2(xyz(ps.pos[j]) - xyz(q)) < r * r;
      }
    }
    c.candidates /= double(c.queries);
    c.neighbours /= double(c.queries);
    return c;
  };
  const Count wide = count(view, std::integral_constant<int, 1>{});
  const Count own = count(anisotropy_grid(view, r), std::integral_constant<int, ComputeAnisotropy::kSpan>{});
  // Every neighbour within the radius, by brute force, for the same queries.
  double brute = 0;
  for (const Vec3f& q : pts) {
    if (!inner({q.x, q.y, q.z, 0.0f})) continue;
    for (const Vec3f& p : pts) brute += length2(p - q) < r * r;
  }
  brute /= double(wide.queries);
  INFO(wide.queries << " queries: view grid " << wide.candidates << " candidates, the pass's grid " << own.candidates
                    << ", for " << brute << " neighbours (the particle itself included)");
  CHECK(wide.queries > 1000);
  CHECK(own.neighbours == Approx(brute).epsilon(1e-12));
  CHECK(wide.neighbours == Approx(brute).epsilon(1e-12));
  CHECK(own.candidates < 0.5 * wide.candidates);
}

TEST_CASE("an ellipsoid's splat box lies within its bound, whatever the settings", "[field]") {
  struct Case {
    const char* stretch;
    const char* smoothing;
    const char* radius;
  };
  for (const Case c : {Case{"4", "0.9", "3"}, Case{"16", "1", "3"}, Case{"1", "0.5", "2"}, Case{"2.5", "0", "4"}}) {
    INFO("stretch " << c.stretch << ", smoothing " << c.smoothing << ", radius " << c.radius);
    const Scene s = aniso_scene({std::string("field.anisotropy.stretch=") + c.stretch,
                                 std::string("field.anisotropy.smoothing=") + c.smoothing,
                                 std::string("field.anisotropy.radius=") + c.radius});
    const FieldSetup fs = make_field_setup(resolve_scene(s));
    const std::vector<Vec3f> pts = liquid(s, 0.3, 300, 11);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> up(0.0f, 1.0f);
    std::vector<float> presence(6 * pts.size());
    for (float& v : presence) v = up(rng);
    const HostParticleSet ps(measure_scene(s).grid, pts, presence);
    const std::vector<Ellipsoid> e = kernels_of(ps, fs);
    const EllipsoidBound bound = EllipsoidBound::of(fs.aniso, fs.geom);
    const uint32_t n = uint32_t(ps.pos.size());
    double worst = 0;  // the largest share of its bound that a side's reach takes
    for (uint32_t p = 0; p < n; ++p) {
      const Vec3f u = fs.geom.to_voxels(xyz(ps.pos[p]));
      const float centre[3] = {e[p].centre.x, e[p].centre.y, e[p].centre.z}, at[3] = {u.x, u.y, u.z};
      const float half[3] = {e[p].half.x, e[p].half.y, e[p].half.z};
      for (int a = 0; a < 3; ++a)
        for (int side = 0; side < 2; ++side) {
          const float ext = fs.shape.extent(ps.presence[(2 * a + side) * n + p]);
          const float reach = side == 0 ? centre[a] + half[a] * ext - at[a] : at[a] - (centre[a] - half[a] * ext);
          worst = std::max(worst, double(reach) / double(bound.reach(ext)));
        }
    }
    INFO("the largest reach is " << worst << " of its bound");
    CHECK(worst <= 1.0);
    CHECK(worst > 0.25);  // the bound is not vacuous (0.29 at stretch 16, which no particle here reaches)
  }
}

// The presence builder's full-cell flags (FullCellFlags) of a view, on the host.
static std::vector<uint8_t> full_cell_flags(const FieldSetup& fs, const ParticleView& v) {
  std::vector<uint8_t> flags(v.grid.num_cells(), 0);
  const FullCellFlags flag{fs.geom, v.grid, v.offsets, fs.full_count, fs.face_count, flags.data()};
  for (uint32_t t = 0; t < flag.num_items(); ++t) flag(t);
  return flags;
}

TEST_CASE("a cell full by count under a surface is not filled whole: a dense pool classifies as naive", "[field]") {
  // Layers 0.93 spacings apart (a compressed liquid): four of them fill a
  // cell by count (64 >= full_count) with the cell's top voxel above the
  // surface. The pool's top is put at several places within a cell; the
  // presence builder without presence must classify every voxel as the naive
  // one does, and the cells full by count under the surface must be among
  // those it does not fill whole.
  const Scene s = aniso_scene();
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  REQUIRE(fs.mark_occupied);
  REQUIRE(fs.full_count <= 64u);
  const GridGeom grid = measure_scene(s).grid;
  const double dx = s.sph.spacing, a = 0.93 * dx, cell = grid.cell_size;
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> jit(-0.05 * dx, 0.05 * dx);
  size_t surface_cells = 0, interior_cells = 0;
  for (double top_in_cell : {0.55, 0.65, 0.72, 0.8, 0.9}) {
    // The top layer at that fraction of the grid's fourth layer of cells.
    const double z0 = grid.origin.z + 3 * cell + top_in_cell * cell;
    std::vector<Vec3f> pts;
    for (double z = z0; z > 0.5 * a; z -= a)
      for (int j = 0; j < 20; ++j)
        for (int i = 0; i < 40; ++i)
          pts.push_back({float((i + 0.5) * dx + jit(rng)), float((j + 0.5) * dx + jit(rng)), float(z + jit(rng))});
    const HostParticleSet ps(grid, pts);
    const ParticleView v = ps.view();
    const std::vector<uint8_t> flags = full_cell_flags(fs, v);
    for (uint32_t c = 0; c < grid.num_cells(); ++c) {
      const bool by_count = v.offsets[c + 1] - v.offsets[c] >= fs.full_count;
      surface_cells += by_count && !flags[c];
      interior_cells += flags[c];
    }
    const std::vector<float> naive = test::cpu_field(fs, v, FieldKind::Naive);
    const std::vector<float> pres = test::cpu_field(fs, v, FieldKind::Presence);
    size_t differ = 0, inside = 0;
    for (size_t q = 0; q < naive.size(); ++q) {
      differ += (naive[q] >= fs.shape.iso) != (pres[q] >= fs.shape.iso);
      inside += naive[q] >= fs.shape.iso;
    }
    INFO("top at " << top_in_cell << " of a cell: " << differ << " of " << inside << " inside voxels differ");
    CHECK(inside > 5000);
    CHECK(differ == 0);
  }
  INFO(surface_cells << " cells full by count and not filled, " << interior_cells << " filled");
  CHECK(surface_cells > 0);   // the case arises
  CHECK(interior_cells > 0);  // and full cells are still filled
}

TEST_CASE("the presence builder leaves out particles deep in full cells, and its field stays the same", "[field]") {
  // A clip no voxel outside the full cells reaches, so that the sums there
  // are compared, not clipped. (A bound a little too small would still pass
  // here, deep particles' boxes lying well inside it: the test above checks
  // the bound itself.)
  const Scene s = aniso_scene({"tank.max=[0.4,0.4,0.4]", "field.clip=1000"});
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  const int nx = 36, ny = 36, nz = 32;
  std::vector<Vec3f> pts;
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> jit(-0.1, 0.1);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        pts.push_back({float((i + 2.5 + jit(rng)) * 0.01), float((j + 2.5 + jit(rng)) * 0.01), float((k + 0.5 + jit(rng)) * 0.01)});
  const HostParticleSet ps(measure_scene(s).grid, pts, block_presence(nx, ny, nz));
  const ParticleView v = ps.view();
  REQUIRE(v.presence);

  // Which particles the ellipsoids' pass leaves out (after the coarse fill, as in a build).
  std::vector<float> field(size_t(fs.geom.num_voxels()), 0.0f);
  REQUIRE(fs.full_fill >= fs.shape.clip);
  const std::vector<uint8_t> flags = full_cell_flags(fs, v);
  const CoarseFill fill{fs.geom, v.grid, v.offsets, fs.shape.coarse, fs.full_fill, flags.data(), field.data()};
  for (uint32_t t = 0; t < fill.num_items(); ++t) fill(t);
  std::vector<Float4> ell(3 * size_t(v.n));
  const EllipsoidPass<ComputeAnisotropy> pass{{v.grid, v.fine_offsets, v.pos, nullptr, v.n, fs.geom, fs.aniso, ell.data()},
                                              field.data(), fs.shape, FullCells{fs.geom, v.grid, flags.data()},
                                              v.presence, EllipsoidBound::of(fs.aniso, fs.geom)};
  uint32_t buried = 0;
  for (uint32_t t = 0; t < v.n; ++t) buried += pass.buried(t, pass.make.particle(t));
  INFO(buried << " of " << v.n << " particles left out");
  CHECK(buried > v.n / 20);
  CHECK(buried < v.n / 2);

  FieldSetup all = fs;
  all.leave_out_buried = false;
  const std::vector<float> with = test::cpu_field(fs, v, FieldKind::Presence);
  const std::vector<float> without = test::cpu_field(all, v, FieldKind::Presence);
  size_t differ = 0, inside = 0;
  float worst = 0;
  for (size_t q = 0; q < with.size(); ++q) {
    differ += (with[q] >= fs.shape.iso) != (without[q] >= fs.shape.iso);
    inside += without[q] >= fs.shape.iso;
    worst = std::max(worst, std::abs(with[q] - without[q]));
  }
  INFO("largest difference " << worst << " (clip " << fs.shape.clip << ")");
  CHECK(inside > 20000);
  CHECK(differ == 0);
  CHECK(worst <= 1e-5f * fs.shape.iso);
}

TEST_CASE("surface error metrics on analytic fields", "[field]") {
  VolumeGeom vol{};
  vol.origin = {0, 0, 0};
  vol.voxel = 0.01f;
  vol.nx = vol.ny = vol.nz = 40;
  vol.refine = 2;
  const size_t n = vol.num_voxels();
  auto fill = [&](auto f) {
    std::vector<float> v(n);
    for (int k = 0; k < 40; ++k)
      for (int j = 0; j < 40; ++j)
        for (int i = 0; i < 40; ++i) v[vol.index(i, j, k)] = float(f((i + 0.5) * 0.01, (j + 0.5) * 0.01, (k + 0.5) * 0.01));
    return v;
  };
  // A plane at z = 0.173 m, field linear in z: found to the bisection's accuracy, normal vertical.
  const std::vector<float> plane = fill([](double, double, double z) { return 0.173 - z; });
  const SurfaceError p = plane_surface_error(plane, vol, 0.0f, {0.05, 0.05, 0.0}, {0.35, 0.35, 0.3}, 0.173, 0.01);
  CHECK(p.rays == 900);
  CHECK(p.missed == 0);
  CHECK(p.rms_distance < 1e-5);
  CHECK(p.rms_angle_deg < 0.01);
  // The same plane tilted by 5 degrees: the tilt is measured.
  const double t = std::tan(5.0 * M_PI / 180.0);
  const std::vector<float> tilted = fill([&](double x, double, double z) { return 0.173 + t * (x - 0.2) - z; });
  const SurfaceError pt = plane_surface_error(tilted, vol, 0.0f, {0.05, 0.05, 0.0}, {0.35, 0.35, 0.3}, 0.173, 0.01);
  CHECK(pt.rms_angle_deg == Approx(5.0).epsilon(0.01));
  CHECK(pt.rms_distance == Approx(t * 0.15 / std::sqrt(3.0)).epsilon(0.03));  // RMS of a uniform ramp over +-0.15 m
  // A sphere of radius 0.12 m from a distance field: within a trilinear field's curvature error.
  const std::vector<float> ball = fill([](double x, double y, double z) {
    return 0.12 - std::sqrt((x - 0.2) * (x - 0.2) + (y - 0.2) * (y - 0.2) + (z - 0.2) * (z - 0.2));
  });
  const SurfaceError b = sphere_surface_error(ball, vol, 0.0f, {0.2, 0.2, 0.2}, 0.12, 500, 0.05);
  CHECK(b.missed == 0);
  CHECK(b.rms_distance < 0.02 * 0.01);
  CHECK(b.rms_angle_deg < 1.0);
  // Measured against a radius 1 voxel off: the offset.
  const SurfaceError b2 = sphere_surface_error(ball, vol, 0.0f, {0.2, 0.2, 0.2}, 0.11, 500, 0.05);
  CHECK(b2.mean_distance == Approx(0.01).epsilon(0.02));
  // A slab with a square hole of 0.1 x 0.1 m in a 0.3 x 0.3 m window; the
  // trilinear field widens it to the neighbouring voxel centres (the hole's
  // -1 outweighs the slab's 0.01 almost up to them): 0.11 x 0.11 m.
  const std::vector<float> slab = fill([](double x, double y, double z) {
    const bool hole = x > 0.1 && x < 0.2 && y > 0.1 && y < 0.2;
    return hole ? -1.0 : 0.01 - std::abs(z - 0.2);
  });
  const SheetHoles h = sheet_holes(slab, vol, 0.0f, {0.05, 0.05, 0.15}, {0.35, 0.35, 0.25}, 0.005);
  CHECK(h.share() == Approx(0.11 * 0.11 / 0.09).epsilon(0.03));
  CHECK(sheet_holes(plane, vol, 0.0f, {0.05, 0.05, 0.15}, {0.35, 0.35, 0.25}, 0.005).holes == 0);
}

TEST_CASE("anisotropic kernels make a flatter, truer pool surface and a truer ball radius", "[field][slow]") {
  // The bench's three liquids at a coarse size (24 particles across; the
  // numbers of docs/field.md come from larger ones). At refine 2 the
  // ellipsoids put the pool's surface nearer its true height with less tilt
  // and the ball's surface nearer its true radius. (The ball's normals are
  // not better: docs/field.md.)
  BenchSurfaceOptions opt;
  opt.cells = 24;
  opt.settle = 0.5;
  opt.warmup = 0;
  opt.frames = 1;
  std::ostringstream log;
  const std::vector<BenchSurfaceRow> rows = bench_surface(Backend::Cpu, opt, log);
  REQUIRE(rows.size() == 9);
  const BenchSurfaceRow *iso = nullptr, *an = nullptr, *zb = nullptr;
  for (const auto& r : rows) {
    if (r.refine == 2) (r.kernel == "anisotropic" ? an : r.kernel == "zhu_bridson" ? zb : iso) = &r;
    CHECK(r.pool.missed == 0);
    CHECK(r.sphere.missed == 0);
  }
  REQUIRE(iso);
  REQUIRE(an);
  REQUIRE(zb);
  // The JSON says which pool it measured (the depth defaults to half the width).
  const nlohmann::json j = to_json(rows, Backend::Cpu, opt);
  CHECK(j["rows"][0]["pool_cells"] == 24);
  CHECK(j["rows"][0]["pool_layers"] == 12);
  print_table(rows, log);
  INFO(log.str());
  CHECK(an->pool.rms_angle_deg < 0.5 * iso->pool.rms_angle_deg);
  CHECK(an->pool.rms_distance < 0.5 * iso->pool.rms_distance);
  CHECK(an->pool.rms_distance < 0.3);  // spacings
  CHECK(an->sphere.rms_distance < 0.5 * iso->sphere.rms_distance);
  CHECK(an->sphere.rms_distance < 0.4);
  CHECK(an->sheet.holes <= iso->sheet.holes);
  // The settled pool is denser than its lattice: its top layer sits lower
  // than the lattice's (0.29 spacing after 1 s, docs/field.md), and against
  // the plane half a spacing above that layer the ellipsoids' surface is
  // nearer than against N dx^3 / area.
  CHECK(an->top_layer_dx > 0.1);
  CHECK(an->top_layer_dx < 0.5);
  CHECK(std::fabs(an->pool_layer.mean_distance) < std::fabs(an->pool.mean_distance));
  // Zhu & Bridson's surface, flat, at the settled pool's particles: within
  // 0.1 spacing of the plane half a spacing above its top layer (measured
  // +0.06 here), below its volume's height by about the packing's deficit,
  // and near the ball's true radius (-0.10).
  CHECK(std::fabs(zb->pool_layer.mean_distance) < 0.1);
  CHECK(zb->pool_layer.rms_distance < 0.12);
  CHECK(zb->pool.mean_distance < -0.1);
  CHECK(zb->pool.rms_angle_deg < 1.0);
  CHECK(zb->sphere.rms_distance < 0.2);
  CHECK(zb->sheet.holes == 0);
}

TEST_CASE("a pool's top layer: the highest particle of each column, averaged", "[field]") {
  // Three layers of 4 x 4 columns at z = 0.5, 1.5, 2.5, the top one
  // uneven; two particles outside [lo, hi] that must not count.
  std::vector<Vec3f> pos;
  double top_sum = 0;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) {
        const float dz = k == 2 ? 0.01f * float(i - j) : 0.0f;
        pos.push_back({float(i) + 0.5f, float(j) + 0.5f, float(k) + 0.5f + dz});
        if (k == 2) top_sum += double(pos.back().z);
      }
  pos.push_back({-1.0f, 0.5f, 9.0f});
  pos.push_back({0.5f, 5.0f, 9.0f});
  CHECK(pool_top_layer(pos, 0.0, 4.0, 3) == Approx(top_sum / 16.0).epsilon(1e-6));
}

TEST_CASE("anisotropy settings are validated by key", "[field][scene]") {
  auto names = [](const std::vector<std::string>& sets, const std::string& part) {
    const std::string e = test::scene_error(R"({"tank": {"min": [0,0,0], "max": [0.4,0.2,0.3]},
      "fluid": [{"min": [0,0,0], "max": [0.12,0.2,0.2]}], "sph": {"spacing": 0.01}, "run": {"end_time": 1}})", sets);
    INFO(e);
    CHECK(test::has(e, part));
  };
  names({"field.kernel=elliptic"}, "field.kernel");
  names({"field.kernel=anisotropic", "field.anisotropy.stretch=0.5"}, "field.anisotropy.stretch");
  names({"field.kernel=anisotropic", "field.anisotropy.smoothing=-0.1"}, "field.anisotropy.smoothing");
  names({"field.kernel=anisotropic", "field.anisotropy.radius=0"}, "field.anisotropy.radius");
  names({"field.kernel=anisotropic", "field.anisotropy.min_neighbours=2.5"}, "field.anisotropy.min_neighbours");
  names({"field.kernel=anisotropic", "field.anisotropy.size=2"}, "unknown key");
  names({"field.kernel=anisotropic", "field.anisotropy.mirror_walls=1"}, "field.anisotropy.mirror_walls");
  names({"field.anisotropy.stretch=2"}, "field.anisotropy");
  names({"field.kernel=anisotropic", "field.builder=gather"}, "field.kernel");
}
