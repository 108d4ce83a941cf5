// CUDA backend against the CPU backend on the same input. Skipped (exit 77,
// reported by ctest as skipped) where no CUDA device is present.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <set>

#include "nsearch/pair_masks.h"
#include "catch.h"
#include "helpers.h"
#include "host_particles.h"
#include "nsearch_probe.h"
#include "hydrostatic.h"
#include "io/export.h"
#include "field/field.h"
#include "io/metrics.h"
#include "render/render.h"

using namespace sphray;

TEST_CASE("cuda grid build equals the cpu grid build", "[gpu]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.05f, 1.05f);
  std::vector<Vec3f> pts(200000);
  for (auto& p : pts) p = {u(rng), u(rng), u(rng)};
  const GridGeom g{{0, 0, 0}, 0.02f, 50, 50, 50};
  const GridBuild c = build_grid(Backend::Cpu, g, pts), d = build_grid(Backend::Cuda, g, pts);
  CHECK(c.offsets == d.offsets);
  CHECK(c.fine_offsets == d.fine_offsets);
  CHECK(c.keys == d.keys);
}

TEST_CASE("cuda three-way split of the passes' particles keeps each list in grid order", "[gpu]") {
  // Across CUB's tiles (thousands of items each) and a million items.
  for (uint32_t n : {0u, 1u, 7u, 100000u, 1000003u}) {
    INFO("n = " << n);
    test::check_partition_three(Backend::Cuda, n, 3 + n);
  }
}

namespace {

// The GPU's shared-tile test may keep a candidate a hair beyond the support
// (BuildPairMask::kTileSlack): each of its lists must hold the cpu's in the
// same order, plus only pairs within a relative 2e-4 of the support squared,
// and those rare. r2_of(k, j): the squared distance of query k to sorted point j.
template <class R2>
void check_gpu_lists_hold_cpu_lists(const PairMaskBuild& cpu, const PairMaskBuild& gpu, double s2, R2&& r2_of) {
  REQUIRE(cpu.grid.order == gpu.grid.order);
  REQUIRE(cpu.neighbours.size() == gpu.neighbours.size());
  size_t pairs = 0, extra = 0;
  for (size_t i = 0; i < cpu.neighbours.size(); ++i) {
    const auto& want = cpu.neighbours[i];
    size_t k = 0;
    for (uint32_t j : gpu.neighbours[i]) {
      if (k < want.size() && want[k] == j) {
        ++k;
        continue;
      }
      ++extra;
      INFO("query " << i << ", extra neighbour " << j << ", r^2 / s^2 = " << r2_of(i, j) / s2);
      REQUIRE(r2_of(i, j) >= s2 * (1.0 - 1e-6));
      REQUIRE(r2_of(i, j) <= s2 * (1.0 + 2e-4));
    }
    REQUIRE(k == want.size());
    pairs += want.size();
  }
  INFO("pairs beyond the support kept by the gpu build: " << extra);
  CHECK(extra <= pairs / 1000);
  CHECK(pairs > 0);
}

double distance2(Vec3f a, Vec3f b) {
  const double dx = double(a.x) - b.x, dy = double(a.y) - b.y, dz = double(a.z) - b.z;
  return dx * dx + dy * dy + dz * dz;
}

}  // namespace

TEST_CASE("cuda pair masks visit the cpu's neighbours in the same order", "[gpu]") {
  // The GPU builds a warp's masks together from shared memory (nsearch/pair_masks.h);
  // the CPU builds each query's own. Walked, both must give every query the
  // same neighbours in the same order: uniform points (a particle count that
  // leaves a partial last warp), a jittered lattice at h = 2 dx (rows shared by
  // a warp's lanes) and at a support of 2.1 spacings in cells of that size
  // (PBF's step grid: a warp spread along its row), a pile-up in one cell
  // (masks overflow), and with few words
  // kept (the direct loop takes over). Both tile tests of the GPU build: the
  // tensor cores' (tile_mma.h; the lattice's warps are compact enough for it,
  // the sparse uniform points' are not and take the FMA test) and the FMA
  // test everywhere.
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> u(0.0f, 1.0f), jit(-0.1f, 0.1f);
  std::vector<Vec3f> uniform(30011), lattice, pile(3000);
  for (auto& p : uniform) p = {u(rng), u(rng), u(rng)};
  for (int z = 0; z < 40; ++z)
    for (int y = 0; y < 40; ++y)
      for (int x = 0; x < 40; ++x)
        lattice.push_back({0.0125f * (x + 0.5f + jit(rng)), 0.0125f * (y + 0.5f + jit(rng)), 0.0125f * (z + 0.5f + jit(rng))});
  for (auto& p : pile) p = {0.54f + 0.03f * u(rng), 0.54f + 0.03f * u(rng), 0.54f + 0.03f * u(rng)};
  const GridGeom wide{{0, 0, 0}, 0.05f, 20, 20, 20};  // support 4 lattice spacings, as h = 2 dx
  // Cells of a support of 2.1 spacings, as PBF's step sorts by: a warp's
  // queries lie along about 3.5 supports of a row, which the tensor test takes.
  const GridGeom narrow{{0, 0, 0}, 0.02625f, 20, 20, 20};
  struct Case { const char* name; const std::vector<Vec3f>* pts; uint32_t capacity; const GridGeom* grid; };
  const Case cases[] = {{"uniform", &uniform, pair_mask_capacity(4.0), &wide},
                        {"lattice", &lattice, pair_mask_capacity(4.0), &wide},
                        {"lattice, 4 words", &lattice, 4u, &wide},
                        {"pile", &pile, pair_mask_capacity(4.0), &wide},
                        {"lattice, support 2.1 spacings", &lattice, pair_mask_capacity(2.1), &narrow}};
  for (const Case& c : cases) {
    INFO(c.name);
    const GridGeom& g = *c.grid;
    const double s2 = double(g.cell_size) * double(g.cell_size);
    const PairMaskBuild cpu = build_pair_masks(Backend::Cpu, g, *c.pts, g.cell_size, c.capacity);
    REQUIRE(cpu.neighbours.size() == c.pts->size());
    size_t pairs = 0;
    for (const auto& l : cpu.neighbours) pairs += l.size();
    for (const bool tensor : {true, false}) {
      INFO((tensor ? "tensor-core tile test" : "FMA tile test"));
      const PairMaskBuild gpu = build_pair_masks(Backend::Cuda, g, *c.pts, g.cell_size, c.capacity, nullptr, tensor);
      check_gpu_lists_hold_cpu_lists(cpu, gpu, s2, [&](size_t i, uint32_t j) {
        return distance2((*c.pts)[cpu.grid.order[i]], (*c.pts)[cpu.grid.order[j]]);
      });
      INFO("neighbours per point " << double(pairs) / double(c.pts->size()) << ", overflowed cpu " << cpu.overflowed
                                   << " gpu " << gpu.overflowed);
      if (c.pts == &pile) CHECK(gpu.overflowed > 0.9 * double(c.pts->size()));
      if (c.capacity == 4u) CHECK(gpu.overflowed > c.pts->size() / 2);
    }
  }
}

TEST_CASE("cuda wall masks with near-cell flags visit the cpu's neighbours", "[gpu]") {
  // The fluid's masks against the walls (another set, with its near-cell
  // flags: a warp whose particles all see no wall stores no words, a lane
  // among others finds its rows empty): a "wall" of points in a slab at
  // x < 0.15, queries everywhere in the cube ordered by x as the solver's
  // sorted fluid is ordered by cell (so that whole warps lie far from the
  // wall; a count that leaves a partial last warp). The gpu lists against the
  // cpu's, and the cpu's against brute force.
  std::mt19937 rng(23);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<Vec3f> wall(60000), queries(20011);
  for (auto& p : wall) p = {0.15f * u(rng), u(rng), u(rng)};
  for (auto& p : queries) p = {u(rng), u(rng), u(rng)};
  std::sort(queries.begin(), queries.end(), [](Vec3f a, Vec3f b) { return a.x < b.x; });
  const GridGeom g{{0, 0, 0}, 0.05f, 20, 20, 20};
  const uint32_t capacity = pair_mask_capacity(4.0);
  const PairMaskBuild cpu = build_pair_masks(Backend::Cpu, g, wall, g.cell_size, capacity, &queries);
  const PairMaskBuild gpu = build_pair_masks(Backend::Cuda, g, wall, g.cell_size, capacity, &queries);
  REQUIRE(cpu.neighbours.size() == queries.size());
  check_gpu_lists_hold_cpu_lists(cpu, gpu, double(g.cell_size) * g.cell_size, [&](size_t k, uint32_t j) {
    return distance2(queries[k], wall[cpu.grid.order[j]]);
  });
  // Every wall neighbour within the support is found (the cpu lists against brute force).
  size_t with = 0, without = 0;
  for (size_t k = 0; k < queries.size(); k += 97) {
    size_t brute = 0;
    for (const Vec3f& w : wall) brute += distance2(queries[k], w) < double(g.cell_size) * g.cell_size * (1.0 - 1e-6);
    REQUIRE(cpu.neighbours[k].size() >= brute);
    REQUIRE(cpu.neighbours[k].size() <= brute + 2);  // pairs within float rounding of the support
    (brute ? with : without) += 1;
  }
  CHECK(with > 10);
  CHECK(without > 10);
}

// The step size is chosen on the device and read back at the end of the
// step (integrate.h, ChooseStep): the guards must still stop the run with the
// cpu's message, and particles leaving through an open top still be counted.
TEST_CASE("cuda guards and open-top removal behave as on the cpu", "[gpu]") {
  {
    const Scene s = load_scene(test::source_path("scenes/stress/jet.json"));
    SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
    in.fluid_vel[17].y = std::numeric_limits<float>::quiet_NaN();
    auto cpu = make_cpu_solver(in), gpu = make_cuda_solver(in);
    const std::string a = test::step_error(*cpu, 1.0), b = test::step_error(*gpu, 1.0);
    CHECK(b.find("particle 17 ") != std::string::npos);
    // The same state found at step 0, the same words up to the acceleration
    // (the pair loop's sums agree to float tolerance, not to the bit).
    const size_t cut = a.find("acceleration (");
    REQUIRE(cut != std::string::npos);
    CHECK(a.substr(0, cut) == b.substr(0, cut));
    CHECK(gpu->steps() == 0);
    CHECK(gpu->time() == 0.0);
  }
  {
    const Scene s = load_scene(test::source_path("scenes/stress/stiff.json"), {"run.min_dt=0.001", "run.max_dt=0.01"});
    auto gpu = make_cuda_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
    const std::string b = test::step_error(*gpu, 1.0);
    CHECK(b.find("run.min_dt") != std::string::npos);
    CHECK(b.find("limit") != std::string::npos);
  }
  {
    const SolverInput in = make_solver_input(resolve_scene(test::dropped_particle_scene(2.0)), PresenceMode::Off);
    auto cpu = make_cpu_solver(in), gpu = make_cuda_solver(in);
    const std::string a = test::run_to_error(*cpu, 0.4), b = test::run_to_error(*gpu, 0.4);
    INFO(a << "\n" << b);
    CHECK(a.find("faster than the speed of sound c0 = 2 m/s") != std::string::npos);
    CHECK(b.find("faster than the speed of sound c0 = 2 m/s") != std::string::npos);
    CHECK(gpu->steps() == cpu->steps());  // a free fall: the same steps to rounding
    CHECK(gpu->time() == Approx(cpu->time()).epsilon(1e-6));
  }
  {
    const Scene s = test::open_top_jet_scene();
    auto gpu = make_cuda_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
    REQUIRE(gpu->num_fluid() == 8);
    test::run_until(*gpu, 0.1);
    CHECK(gpu->num_removed() == 8);
    CHECK(gpu->num_fluid() == 0);
    CHECK(std::abs(gpu->time() - 0.1) < 1e-12);
  }
}

// The largest differences between two backends' particles, matched by id.
struct Worst {
  double pos = 0, rho = 0, presence = 0;
};
Worst worst_by_id(const HostParticles& a, const HostParticles& b) {
  REQUIRE(a.pos.size() == b.pos.size());
  std::vector<size_t> where(a.id.size());
  for (size_t k = 0; k < b.id.size(); ++k) where[b.id[k]] = k;
  Worst w;
  for (size_t k = 0; k < a.id.size(); ++k) {
    const size_t m = where[a.id[k]];
    w.pos = std::max(w.pos, double(length(a.pos[k] - b.pos[m])));
    w.rho = std::max(w.rho, double(std::abs(a.density[k] - b.density[m])));
    for (int d = 0; d < 6; ++d) w.presence = std::max(w.presence, double(std::abs(a.presence[k][d] - b.presence[m][d])));
  }
  return w;
}

TEST_CASE("cuda and cpu dam breaks agree to float tolerance", "[gpu]") {
  const Scene s = load_scene(test::source_path("scenes/dam_break.json"), {"sph.spacing=0.02", "sph.presence=true"});
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::EveryStep);
  auto cpu = make_cpu_solver(in), gpu = make_cuda_solver(in);
  for (int k = 0; k < 50; ++k) {
    cpu->step(1.0);
    gpu->step(1.0);
    REQUIRE(std::abs(cpu->last_limits().dt - gpu->last_limits().dt) <= 1e-3 * cpu->last_limits().dt);
  }
  test::check_flow_sums(*gpu);  // the metrics' reductions on the device
  const Worst w = worst_by_id(cpu->download(), gpu->download());
  INFO("worst position difference " << w.pos << " m, density " << w.rho << ", presence " << w.presence);
  CHECK(w.pos < 1e-3 * s.sph.spacing);
  CHECK(w.rho < 1e-3 * s.sph.rest_density);
  CHECK(w.presence < 1e-3);
}

// The incompressible solvers on both backends: the particles agree to float
// tolerance over the first steps, and the run's statistics over twenty more.
// Their rounding grows faster than WCSPH's (PBF's one-sided constraint;
// DFSPH's solves stop at a tolerance, and the backends' sums may stop them one
// iteration apart).
struct BackendPair {
  std::unique_ptr<Solver> cpu, gpu;
  void step(int k) {
    for (int i = 0; i < k; ++i) {
      cpu->step(1.0);
      gpu->step(1.0);
    }
  }
};
BackendPair compare_first_steps(const std::string& solver) {
  const Scene s = load_scene(test::source_path("scenes/dam_break.json"),
                             {"sph.spacing=0.02", "sph.solver=" + solver, "sph.presence=true"});
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::EveryStep);
  BackendPair b{make_cpu_solver(in), make_cuda_solver(in)};
  for (int k = 0; k < 3; ++k) {
    b.step(1);
    REQUIRE(std::abs(b.cpu->last_limits().dt - b.gpu->last_limits().dt) <= 1e-3 * b.cpu->last_limits().dt);
    if (solver == "pbf") REQUIRE(b.cpu->last_solve().iterations == b.gpu->last_solve().iterations);
  }
  const Worst w = worst_by_id(b.cpu->download(), b.gpu->download());
  INFO(solver << ": worst position difference " << w.pos << " m, density " << w.rho << ", presence " << w.presence);
  CHECK(w.pos < 1e-3 * s.sph.spacing);
  CHECK(w.rho < 1e-3 * s.sph.rest_density);
  CHECK(w.presence < 1e-3);
  b.step(20);
  const SolveStats sc = b.cpu->last_solve(), sg = b.gpu->last_solve();
  const double vc = b.cpu->last_limits().max_speed, vg = b.gpu->last_limits().max_speed;
  INFO(solver << ": density error cpu " << sc.density_error_mean << ", cuda " << sg.density_error_mean
              << "; iterations cpu " << sc.iterations << ", cuda " << sg.iterations << "; max speed cpu " << vc
              << ", cuda " << vg);
  CHECK(std::abs(sc.density_error_mean - sg.density_error_mean) <= 0.1 * sc.density_error_mean + 1e-4);
  CHECK(std::abs(sc.iterations - sg.iterations) <= 2);
  CHECK(std::abs(vc - vg) <= 0.1 * vc);
  test::check_flow_sums(*b.cpu);
  test::check_flow_sums(*b.gpu);
  return b;
}

TEST_CASE("cuda and cpu pbf dam breaks agree to float tolerance", "[gpu]") { compare_first_steps("pbf"); }

TEST_CASE("cuda and cpu dfsph dam breaks agree to float tolerance", "[gpu]") {
  const BackendPair b = compare_first_steps("dfsph");
  // The pressure field agrees as well (the hydrostatic test's quantity).
  const std::vector<float> pc = b.cpu->pressures(), pg = b.gpu->pressures();
  REQUIRE(pc.size() == pg.size());
  double sum_c = 0, sum_g = 0;
  for (size_t k = 0; k < pc.size(); ++k) { sum_c += pc[k]; sum_g += pg[k]; }
  CHECK(std::abs(sum_g / sum_c - 1.0) < 0.02);
}

TEST_CASE("cuda export snapshots hold the state they were taken at, while the run goes on", "[gpu]") {
  // The copy off the device runs on a stream of its own behind the next
  // steps (AsyncDownload): a frame made after them must still be the state
  // at its capture, and match the cpu's frame of the same steps.
  const Scene s = load_scene(test::source_path("scenes/dam_break.json"), {"sph.spacing=0.02", "sph.presence=true"});
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::EveryStep);
  auto cpu = make_cpu_solver(in), gpu = make_cuda_solver(in);
  const SphParams prm = make_params(s);
  const std::set<std::string> fields = parse_export_fields("velocity,density,presence");
  for (int k = 0; k < 20; ++k) {
    cpu->step(1.0);
    gpu->step(1.0);
  }
  const HostParticles at = gpu->download();
  auto make = capture_frame(*gpu, prm, fields, nullptr);
  auto make_second = capture_frame(*gpu, prm, fields, nullptr);  // waits for the first's copies, then its own
  for (int k = 0; k < 10; ++k) gpu->step(1.0);  // the run goes on, re-sorting and moving every particle
  const Frame f = *make(), f2 = *make_second();
  const Frame c = frame_of(*cpu, prm, fields, nullptr);
  REQUIRE(f.count() == at.id.size());
  std::vector<size_t> where(at.id.size());
  for (size_t k = 0; k < at.id.size(); ++k) where[at.id[k]] = k;
  double worst_cpu = 0;
  for (size_t r = 0; r < f.count(); ++r) {
    const size_t k = where[f.id[r]];
    for (int d = 0; d < 3; ++d) {
      REQUIRE(f.position[3 * r + d] == (&at.pos[k].x)[d]);  // exactly the state at capture
      REQUIRE(f.velocity[3 * r + d] == (&at.vel[k].x)[d]);
      worst_cpu = std::max(worst_cpu, double(std::abs(f.position[3 * r + d] - c.position[3 * r + d])));
    }
    REQUIRE(f.density[r] == at.density[k]);
    for (int d = 0; d < 6; ++d) REQUIRE(f.presence[6 * r + d] == at.presence[k][d]);
  }
  CHECK(f2.position == f.position);
  CHECK(c.id == f.id);
  CHECK(worst_cpu < 1e-3 * s.sph.spacing);
}

TEST_CASE("cuda hydrostatic tank: pressure error against spacing and speed of sound", "[gpu]") {
  // The cpu test's tank (1 cm, 2880 particles) at 5 and 2.5 mm (23k and 184k
  // particles) with the automatic c0 = 10 sqrt(g H) = 14 m/s, then at 5 mm with
  // c0 2x and 4x that. The pressure excess is a weakly-compressible effect
  // (density varies by g H / c0^2 = 1% over the column at 14 m/s): it barely
  // moves with the spacing and falls with c0^2 (docs/validation.md).
  auto report = [](const test::Hydrostatic& r, double dx, double c0) {
    std::cout << "hydrostatic dx " << dx << " c0 " << (c0 > 0 ? std::to_string(c0) : "auto") << ": " << r.particles
              << " particles, dp/dz " << 100 * r.slope_error() << "%, bottom " << 100 * r.bottom_error() << "% ("
              << r.bottom_p << " vs " << r.bottom_w << " Pa)" << std::endl;
  };
  double previous = 0;  // the bottom error at 5 mm, then at each stiffer c0
  for (const double dx : {0.01, 0.005, 0.0025}) {
    const test::Hydrostatic r = test::run_hydrostatic(Backend::Cuda, dx);
    report(r, dx, 0);
    INFO("dx " << dx << ": dp/dz " << 100 * r.slope_error() << "%, bottom " << 100 * r.bottom_error() << "%");
    CHECK(r.all_inside);
    CHECK(r.clamped == 0);
    CHECK(std::abs(r.slope_error()) < 0.02);
    CHECK(std::abs(r.bottom_error()) < 0.025);
    if (dx == 0.005) previous = std::abs(r.bottom_error());
  }
  for (const double c0 : {28.0, 56.0}) {
    const test::Hydrostatic r = test::run_hydrostatic(Backend::Cuda, 0.005, c0);
    report(r, 0.005, c0);
    INFO("c0 " << c0 << ": dp/dz " << 100 * r.slope_error() << "%, bottom " << 100 * r.bottom_error() << "%");
    CHECK(r.all_inside);
    CHECK(std::abs(r.slope_error()) < 0.02);
    CHECK(std::abs(r.bottom_error()) < 0.02);
    CHECK(std::abs(r.bottom_error()) < 0.6 * previous);  // falls with c0 (about as 1/c0^2)
    previous = std::abs(r.bottom_error());
  }
}

TEST_CASE("cuda field builders agree with the cpu builders", "[gpu]") {
  const std::string kernel = GENERATE(std::string("isotropic"), std::string("anisotropic"), std::string("zhu_bridson"));
  INFO("field.kernel " << kernel);
  const Scene s = load_scene(test::source_path("scenes/dam_break.json"),
                             {"sph.spacing=0.02", "field.refine=2", "run.end_time=1", "field.kernel=" + kernel});
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::EveryStep);
  auto cpu = make_cpu_solver(in), gpu = make_cuda_solver(in);
  for (int k = 0; k < 20; ++k) {
    cpu->step(1.0);
    gpu->step(1.0);
  }
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  // Ellipsoids from the sums of WCSPH's pair loop on both backends (sph/covariance.h).
  CHECK(bool(cpu->view().covariance) == (fs.kernel == FieldKernel::Anisotropic));
  CHECK(bool(gpu->view().covariance) == (fs.kernel == FieldKernel::Anisotropic));
  // Ellipsoids also from the field's own covariance pass (as under PBF and
  // DFSPH: the views without the sums), with the walls' images in both.
  for (int own = 0; own < (fs.kernel == FieldKernel::Anisotropic ? 2 : 1); ++own) {
    for (FieldKind kind : {FieldKind::Naive, FieldKind::Presence, FieldKind::Gather}) {
      if (fs.kernel == FieldKernel::Anisotropic && kind == FieldKind::Gather) continue;  // spheres only
      if (fs.kernel == FieldKernel::ZhuBridson && kind != FieldKind::Gather) continue;  // the gather builder's alone
      ParticleView vc = cpu->view(), vg = gpu->view();
      if (own) vc.covariance = vg.covariance = nullptr;
      INFO((own ? "the field's own covariance pass" : "the solver's sums"));
      auto fc = make_cpu_field_builder(fs, kind), fg = make_cuda_field_builder(fs, kind);
      fc->build(vc, true);
      const std::vector<float> a = fc->download();
      for (int group : {1, 4, 8, 32}) {  // every thread layout (the sphere gather: one thread per voxel)
        if (kind == FieldKind::Gather && fs.kernel != FieldKernel::ZhuBridson && group != 1) continue;
        fg->build(vg, true, group);
        const std::vector<float> b = fg->download();
        double worst = 0;
        for (size_t v = 0; v < a.size(); ++v) worst = std::max(worst, std::abs(double(a[v]) - b[v]) / (1.0 + a[v]));
        const FieldError e = compare_fields(fs.geom.nx, fs.geom.ny, fs.geom.nz, a, b, fs.shape.iso);
        INFO(field_kind_name(kind) << ", " << group << " threads per particle: worst relative difference " << worst
                                   << ", misclassified " << e.misclassified_band << " of " << e.band);
        CHECK(e.misclassified_share() < 1e-3);
        CHECK(e.misclassified_other == 0);
        if (kind != FieldKind::Presence) CHECK(worst < 1e-3);  // the presence splat's order decides where clipping lands
        CHECK(fg->last_counts().counted);
        CHECK(double(fg->last_counts().touched) == Approx(double(fc->last_counts().touched)).epsilon(0.01));
      }
    }
  }
  // Zhu & Bridson's surface at coarser voxels, where the GPU's default is
  // several threads per voxel (FieldBuilderImpl::zhu_bridson_group).
  if (fs.kernel != FieldKernel::ZhuBridson) return;
  for (int refine : {0, 1}) {
    const FieldSetup coarse = make_field_setup(
        resolve_scene(load_scene(test::source_path("scenes/dam_break.json"), {"sph.spacing=0.02", "run.end_time=1",
                                                                              "field.kernel=zhu_bridson",
                                                                              "field.refine=" + std::to_string(refine)})));
    auto fc = make_cpu_field_builder(coarse, FieldKind::Gather), fg = make_cuda_field_builder(coarse, FieldKind::Gather);
    fc->build(cpu->view());
    fg->build(gpu->view());
    const std::vector<float> a = fc->download(), b = fg->download();
    double worst = 0;
    for (size_t v = 0; v < a.size(); ++v) worst = std::max(worst, std::abs(double(a[v]) - b[v]) / (1.0 + a[v]));
    INFO("zhu_bridson at refine " << refine << ": worst relative difference " << worst);
    CHECK(worst < 1e-3);
  }
}

TEST_CASE("cuda renders agree with the cpu renders: raycast, slices, screen space", "[gpu]") {
  const Scene s = load_scene(test::source_path("scenes/dam_break.json"),
                             {"sph.spacing=0.02", "run.end_time=1", "render.width=320", "render.height=180"});
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
  auto cpu = make_cpu_solver(in), gpu = make_cuda_solver(in);
  const FieldSetup fs = make_field_setup(resolve_scene(s));
  auto fc = make_cpu_field_builder(fs, FieldKind::Naive), fg = make_cuda_field_builder(fs, FieldKind::Naive);
  fc->build(cpu->view());
  fg->build(gpu->view());
  const Camera cam = make_camera(s.tank, s.render);
  const Environment env = make_environment(s.tank, fs.geom, cam);
  auto rc = make_cpu_renderer(), rg = make_cuda_renderer();
  for (int interfaces : {1, 4, 8})
    for (bool reflections : {false, true}) {
      RenderSettings rs = s.render;
      rs.interfaces = interfaces;
      rs.reflections = reflections;
      for (RenderMethod m : {RenderMethod::Raycast, RenderMethod::Slices, RenderMethod::ScreenSpace}) {
        if (m == RenderMethod::ScreenSpace && (interfaces != 4 || reflections)) continue;  // it takes neither
        rs.method = m;
        rc->render(RenderInput{fc->data(), &fs, cpu->view(), s.sph.spacing}, cam, env, rs);
        rg->render(RenderInput{fg->data(), &fs, gpu->view(), s.sph.spacing}, cam, env, rs);
        const Image a = rc->download(), b = rg->download();
        const size_t differ = pixels_differing(a, b, 3);
        INFO(render_method_name(m) << ", " << interfaces << " interfaces, reflections " << reflections << ": PSNR "
                                   << psnr(a, b) << " dB, " << differ << " pixels differ by more than 3 levels");
        CHECK(psnr(a, b) > 40.0);
        CHECK(differ < a.rgba.size() / 200);
      }
    }
}
