// Divergence-free SPH (sph/dfsph.h): hydrostatic pressure against rho0 g d,
// the solves' tolerances and limits, the guards, the scene's "dfsph" options, and the dam break's front against
// SPlisHSPlasH's DFSPH on the same scene. The rest state at the mirror walls
// is tested with PBF's (test_pbf.cpp).
#include <algorithm>
#include <cmath>
#include <string>

#include "catch.h"
#include "helpers.h"
#include "io/export.h"
#include "io/metrics.h"

using namespace sphray;

namespace {

Scene dfsph_scene(const std::string& file, std::vector<std::string> overrides) {
  overrides.push_back("sph.solver=dfsph");
  return load_scene(test::source_path(file), overrides);
}

}  // namespace

TEST_CASE("dfsph: a column at rest holds hydrostatic pressure within 2% of rho0 g d", "[sph][cpu]") {
  // 0.12 x 0.12 x 0.2 m at dx = 1 cm (2880 particles). The pressure of one
  // step is noisy (a solve that stops at a tolerance lets the column settle
  // a little and then pushes back), so each particle's pressure is averaged
  // over the steps of 0.2-0.4 s, weighted by their length. Reference 1: the
  // least-squares slope of the pressure over height between 20% and 90%
  // depth against rho g (the hydrostatic law). Reference 2: the bottom
  // layer's pressure against the weight of the liquid above it per unit
  // area (each particle, of mass rho0 V, smeared over one spacing in height):
  // measured 2.4% above it at this spacing, the pressure field offset by
  // about half a spacing at the free surface, so within 3%.
  const Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.12,0.12,0.3]},
    "fluid": [{"min": [0,0,0], "max": [0.12,0.12,0.2]}],
    "sph": {"spacing": 0.01, "solver": "dfsph"}, "run": {"end_time": 0.4}})", "column.json");
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  test::run_until(*solver, 0.2);
  const size_t n_all = solver->num_fluid();
  std::vector<double> p_sum(n_all, 0.0);
  double t_sum = 0;
  while (solver->time() < 0.4 - 1e-12) {
    solver->step(0.4);
    const HostParticles h = solver->download();
    const std::vector<float> pr = solver->pressures();
    REQUIRE(pr.size() == h.id.size());
    const double dt = solver->last_limits().dt;
    for (size_t k = 0; k < pr.size(); ++k) p_sum[h.id[k]] += pr[k] * dt;
    t_sum += dt;
  }
  const HostParticles p = solver->download();
  const double H = 0.2, g = 9.81, rho0 = s.sph.rest_density, dx = s.sph.spacing, area = 0.12 * 0.12;
  const double mass = rho0 * resolve_scene(s).dfsph.volume;
  std::vector<double> zs;
  for (const Vec3f& x : p.pos) zs.push_back(x.z);
  std::sort(zs.begin(), zs.end());
  double sz = 0, sp = 0, szz = 0, szp = 0, srho = 0, bottom = 0, bottom_ref = 0;
  size_t n = 0, nb = 0;
  for (size_t k = 0; k < p.pos.size(); ++k) {
    const double z = p.pos[k].z, depth = H - z, pk = p_sum[p.id[k]] / t_sum;
    if (depth >= 0.2 * H && depth <= 0.9 * H) {
      sz += z; sp += pk; szz += z * z; szp += z * pk; srho += p.density[k];
      ++n;
    }
    if (z < dx) {
      double above = double(zs.end() - std::upper_bound(zs.begin(), zs.end(), z + 0.5 * dx));
      for (auto it = std::lower_bound(zs.begin(), zs.end(), z - 0.5 * dx); it != zs.end() && *it <= z + 0.5 * dx; ++it)
        above += std::clamp((*it - z) / dx + 0.5, 0.0, 1.0);
      bottom += pk;
      bottom_ref += g * mass * above / area;
      ++nb;
    }
  }
  const double slope = (n * szp - sz * sp) / (n * szz - sz * sz), rho_g = srho / n * g;
  INFO("dp/dz " << slope << " Pa/m against -rho g " << -rho_g << "; bottom layer " << bottom / nb << " Pa against "
                << bottom_ref / nb);
  CHECK(std::abs(-slope / rho_g - 1.0) < 0.02);
  CHECK(std::abs(bottom / bottom_ref - 1.0) < 0.03);
  CHECK(solver->last_limits().max_speed < 0.1 * std::sqrt(g * H));
}

TEST_CASE("dfsph: no particle leaves a closed tank or comes closer to a wall than dfsph.wall_margin, the step follows "
          "the flow CFL, the density error meets the tolerance",
          "[sph][cpu]") {
  const Scene s = dfsph_scene("scenes/dam_break.json", {"sph.spacing=0.04", "run.end_time=0.6"});
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const size_t n = solver->num_fluid();
  Aabb tank = resolve_scene(s).params.tank;  // the walls in the solver's single precision
  const float margin = float(0.999 * s.sph.dfsph.wall_margin * s.sph.spacing);
  REQUIRE(margin > 0.0f);
  tank.min = tank.min + Vec3f{margin, margin, margin};
  tank.max = tank.max - Vec3f{margin, margin, margin};
  double worst_cfl = 0, error_sum = 0;
  int steps = 0, unconverged = 0;
  while (solver->time() < s.run.end_time - 1e-12) {
    solver->step(s.run.end_time);
    const StepLimits& l = solver->last_limits();
    worst_cfl = std::max(worst_cfl, l.dt * l.max_speed / s.sph.spacing);
    const SolveStats st = solver->last_solve();
    REQUIRE(st.iterations >= s.sph.dfsph.min_iterations);
    REQUIRE(st.iterations <= s.sph.dfsph.max_iterations);
    REQUIRE(st.divergence_iterations >= 1);
    error_sum += st.density_error_mean;
    unconverged += st.converged ? 0 : 1;
    ++steps;
    const HostParticles p = solver->download();
    REQUIRE(p.pos.size() == n);
    for (const Vec3f& x : p.pos) REQUIRE(test::inside(x, tank));
  }
  CHECK(worst_cfl <= 1.01 * s.sph.cfl + 1e-9);
  CHECK(unconverged == 0);
  // The state's compression after the advection, against the solve's target.
  INFO("mean density error " << error_sum / steps);
  CHECK(error_sum / steps < 2 * s.sph.dfsph.tolerance);
}

TEST_CASE("dfsph: a block collapsing into a corner stays stable and within its tolerance at wide supports, with "
          "either kernel",
          "[sph][cpu]") {
  // 1,000 particles released in the corner of a tank twice their size, 0.25 s.
  // A weight of 0.5 would let the solves' fastest modes grow from 2.44
  // spacings (cubic spline) and 2.55 (Wendland C2); the weight from the kernel's spectrum (DfsphParams::jacobi_weight) keeps them
  // converging.
  const double end = 0.25;
  for (const std::string kernel : {"cubic_spline", "wendland_c2"})
    for (const std::string support : {"2.5", "3", "4"}) {
      const Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.4,0.4,0.4]},
        "fluid": [{"min": [0,0,0], "max": [0.2,0.2,0.2]}],
        "sph": {"spacing": 0.02, "solver": "dfsph"}, "dfsph": {"kernel": ")" + kernel + R"(", "support": )" + support + R"(}})",
                                  "corner.json");
      auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
      double error_sum = 0, fastest = 0;
      int steps = 0, unconverged = 0;
      while (solver->time() < end - 1e-12) {
        solver->step(end);
        error_sum += solver->last_solve().density_error_mean;
        unconverged += solver->last_solve().converged ? 0 : 1;
        fastest = std::max(fastest, solver->last_limits().max_speed);
        ++steps;
      }
      INFO(kernel << ", support " << support << ": " << steps << " steps, mean density error " << error_sum / steps
                  << ", fastest " << fastest << " m/s, " << unconverged << " steps unconverged");
      CHECK(unconverged == 0);
      CHECK(error_sum / steps < 2 * s.sph.dfsph.tolerance);
      // The collapse of a 0.2 m column: its front at about 2 sqrt(g H) = 2.8 m/s.
      CHECK(fastest < 2 * 2.8);
    }
}

TEST_CASE("dfsph: a viscous dam break's kinetic energy stays within the potential energy it has released", "[sph][cpu]") {
  // dfsph.viscosity = 0.1 m^2/s (a honey-like liquid: the step is held by
  // the explicit viscosity's limit, max_dt_viscous). Energy can only be
  // released by the fall and taken by the viscosity: KE(t) <= PE(0) - PE(t),
  // and step by step. Beside the walls a particle's own image adds to the
  // operator's bulk rate (pipeline/setup.cpp), which the limit must cover.
  const Scene s = dfsph_scene("scenes/dam_break.json", {"sph.spacing=0.04", "dfsph.viscosity=0.1", "run.end_time=0.6"});
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const double m = s.sph.rest_density * resolve_scene(s).dfsph.volume, g = 9.81;
  auto energies = [&](double& kinetic, double& potential) {
    const HostParticles p = solver->download();
    kinetic = potential = 0;
    for (size_t k = 0; k < p.pos.size(); ++k) {
      kinetic += 0.5 * m * double(length2(p.vel[k]));
      potential += m * g * p.pos[k].z;
    }
  };
  double k0 = 0, pe0 = 0;
  energies(k0, pe0);
  double ke_last = k0, pe_last = pe0, worst = -1e9, worst_step = -1e9, peak = 0;
  while (solver->time() < s.run.end_time - 1e-12) {
    solver->step(s.run.end_time);
    double ke = 0, pe = 0;
    energies(ke, pe);
    worst = std::max(worst, ke - (pe0 - pe));
    // Step by step as well: a step's gain in kinetic energy against what its fall released.
    worst_step = std::max(worst_step, (ke - ke_last) - (pe_last - pe));
    ke_last = ke, pe_last = pe;
    peak = std::max(peak, ke);
  }
  INFO("largest kinetic energy " << peak << " J; largest excess over the released energy " << worst
                                 << " J, over a step's " << worst_step << " J");
  CHECK(k0 == 0.0);
  CHECK(peak > 0.5);  // it flows
  // (The first step is a free fall, kinetic energy gained = potential energy
  // released: a millijoule for round-off.)
  CHECK(worst <= 1e-3);
  CHECK(worst_step <= 1e-3);
}

TEST_CASE("dfsph: the iteration limits bound the solves, and a step that hits one is counted", "[sph][cpu]") {
  // Far below a tolerance of 1e-9 no step converges: every pressure solve
  // runs to its limit.
  const Scene tight = dfsph_scene("scenes/dam_break.json", {"sph.spacing=0.04", "dfsph.tolerance=1e-9",
                                                            "dfsph.max_iterations=3", "dfsph.max_divergence_iterations=2"});
  auto a = make_cpu_solver(make_solver_input(resolve_scene(tight), PresenceMode::Off));
  for (int k = 0; k < 5; ++k) a->step(1.0);
  CHECK(a->last_solve().iterations == 3);
  CHECK(a->last_solve().divergence_iterations <= 2);
  CHECK_FALSE(a->last_solve().converged);
  // A loose tolerance stops at the minimum.
  const Scene loose = dfsph_scene("scenes/dam_break.json", {"sph.spacing=0.04", "dfsph.tolerance=0.5",
                                                            "dfsph.min_iterations=4"});
  auto b = make_cpu_solver(make_solver_input(resolve_scene(loose), PresenceMode::Off));
  b->step(1.0);
  CHECK(b->last_solve().iterations == 4);
  CHECK(b->last_solve().converged);
}

TEST_CASE("dfsph: a diverging run stops with the step named", "[sph][cpu]") {
  // A block thrown at a wall at 200 m/s with one pressure iteration and steps
  // of ten spacings piles onto the wall, projected onto it (no wall margin:
  // with the default margin the same block survives 20 s): the pressure of
  // one iteration throws particles at absurd speeds, and the run stops on
  // whichever guard trips first (the step falling below run.min_dt, the
  // density error past 100%, a non-finite value), naming the step.
  Scene s = dfsph_scene("scenes/dam_break.json", {"sph.spacing=0.04", "dfsph.min_iterations=1", "dfsph.max_iterations=1",
                                                  "sph.cfl=10", "run.max_dt=0.1", "dfsph.wall_margin=0"});
  s.fluid[0] = {{{0.2, 0.0, 0.0}, {0.6, 0.67, 0.3}}, {-200.0, 0.0, 0.0}};
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const std::string message = test::run_to_error(*solver, 100.0);
  INFO(message);
  CHECK((test::has(message, "at step") || test::has(message, "(step ")));
  CHECK((test::has(message, "DFSPH density error diverged") || test::has(message, "non-finite") ||
         test::has(message, "fell below the floor run.min_dt")));
}

TEST_CASE("dfsph scene options: refused by name where they do not apply or are out of range", "[scene][cpu]") {
  const std::string base = R"({"tank": {"min": [0,0,0], "max": [1,1,1]}, "fluid": [{"min": [0,0,0], "max": [0.5,0.5,0.5]}], )";
  auto error_of = [&](const std::string& rest) { return test::scene_error(base + rest); };
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "isph"}})"), "\"wcsph\", \"pbf\", \"dfsph\""));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph", "viscosity_alpha": 0.1}})"),
                  "sph.viscosity_alpha"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1}, "dfsph": {"tolerance": 0.01}})"), "dfsph"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "pbf"}, "dfsph": {"tolerance": 0.01}})"), "dfsph"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "pbf": {"iterations": 3}})"), "pbf"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"tolerance": 0}})"),
                  "dfsph.tolerance"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"wall_margin": -0.1}})"),
                  "dfsph.wall_margin"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"divergence_tolerance": -1}})"),
                  "dfsph.divergence_tolerance"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"max_iterations": 0}})"),
                  "dfsph.max_iterations"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"min_iterations": 5, "max_iterations": 4}})"),
                  "dfsph.max_iterations"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"kernel": "gauss"}})"),
                  "dfsph.kernel"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"iterations": 3}})"),
                  "dfsph.iterations"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph", "cfl": 0}})"), "sph.cfl"));
  CHECK(test::has(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "run": {"min_dt": 0.01, "max_dt": 0.001}})"),
                  "run.max_dt"));
  CHECK(error_of(R"("sph": {"spacing": 0.1, "solver": "dfsph"}, "dfsph": {"viscosity": "auto", "kernel": "wendland_c2"}})")
            .empty());
  const Scene d = parse_scene(base + R"("sph": {"spacing": 0.1, "solver": "dfsph"}})", "s.json");
  CHECK(d.sph.cfl == SphConfig::kDfsphCfl);
  CHECK(d.run.max_dt == Scene::Run::kFlowMaxDt);
  CHECK(d.sph.wall_layers() == 0);
  CHECK(d.sph.grid_cell() == Approx(2 * d.sph.dfsph.support * 0.1));
}

TEST_CASE("dfsph: the dam break's front follows SPlisHSPlasH's DFSPH on the same scene within 5%", "[validation][slow][cpu]") {
  // dx = 2 cm, 9,900 particles (data/splishsplash_dfsph_dam_break.csv: a
  // code-to-code reference with another boundary model and kernel support).
  const Scene s = dfsph_scene("scenes/dam_break.json", {"run.end_time=0.5", "run.output_interval=0.1"});
  REQUIRE(s.sph.spacing == 0.02);
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  const Curve ref = read_csv_curve(test::source_path("data/splishsplash_dfsph_dam_break.csv"));
  for (double t : {0.1, 0.2, 0.3, 0.4, 0.5}) {
    test::run_until(*solver, t);
    const double front = surge_front(solver->download(), 0.0, s.sph.spacing), want = interpolate(ref, t);
    INFO("t = " << t << " s: front " << front << " m, SPlisHSPlasH " << want << " m");
    CHECK(std::abs(front / want - 1.0) < 0.05);
  }
}

TEST_CASE("dfsph: the exported pressure field is the solver's pressure, row by id", "[export][cpu]") {
  const Scene s = dfsph_scene("scenes/dam_break.json", {"sph.spacing=0.04"});
  const ResolvedScene r = resolve_scene(s);
  auto solver = make_cpu_solver(make_solver_input(r, PresenceMode::Off));
  // Before the first step no solve has run: zero, not 0 / 0.
  const Frame at_start = frame_of(*solver, r.params, parse_export_fields("pressure"), nullptr);
  REQUIRE(at_start.pressure.size() == solver->num_fluid());
  for (float v : at_start.pressure) REQUIRE(v == 0.0f);
  for (int k = 0; k < 5; ++k) solver->step(1.0);
  const Frame f = frame_of(*solver, r.params, parse_export_fields("pressure"), nullptr);
  const HostParticles h = solver->download();
  const std::vector<float> p = solver->pressures();
  REQUIRE(f.pressure.size() == p.size());
  double largest = 0;
  for (size_t k = 0; k < p.size(); ++k) {
    REQUIRE(f.id[h.id[k]] == h.id[k]);  // every particle present: row = id
    CHECK(f.pressure[h.id[k]] == p[k]);
    largest = std::max(largest, double(p[k]));
  }
  CHECK(largest > 0);  // a column under gravity has pressure
}
