// The shared machinery: named launches and their timing, the scene-section
// reader, the equation of state, and the defaults each stage keeps once.
#include <cmath>
#include <set>
#include <string>

#include "catch.h"
#include "core/config_reader.h"
#include "core/kernel_times.h"
#include "helpers.h"
#include "sph/eos.h"

using namespace sphray;

namespace {

std::string error_of(const nlohmann::json& j, double lo, double hi) {
  try {
    const ConfigReader r(j, "f.json", "sec");
    r.only({"a"});
    r.number("a", 0, lo, hi);
  } catch (const SceneError& e) {
    return e.what();
  }
  return {};
}

}  // namespace

TEST_CASE("named launches are timed by name only while kernel timing is on", "[core][cpu]") {
  const Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.2,0.1,0.2]},
    "fluid": [{"min": [0,0,0], "max": [0.08,0.1,0.1]}], "sph": {"spacing": 0.01}})", "t.json");
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
  take_kernel_times();
  solver->step(1.0);
  CHECK(take_kernel_times().empty());  // off by default

  set_kernel_timing(true);
  solver->step(1.0);
  set_kernel_timing(false);
  const std::vector<KernelTime> times = take_kernel_times();
  std::set<std::string> names;
  double sum = 0;
  for (const KernelTime& k : times) {
    names.insert(k.name);
    CHECK(k.launches >= 1);
    CHECK(k.ms >= 0);
    sum += k.ms;
  }
  for (const char* stage : {"wall_pressure", "pair_loop", "choose_step", "advance", "fluid_keys", "gather_particles",
                            "fluid_pair_masks", "wall_pair_masks"})
    CHECK(names.count(stage) == 1);
  // The launches lie inside the step's stages (the sort and reduce are not launches of parallel_for).
  CHECK(sum <= solver->last_stage_times().total() + 0.5);
  CHECK(take_kernel_times().empty());  // taken
}

TEST_CASE("a scene section's reader names file, key and value, and the allowed keys", "[core][cpu]") {
  CHECK(error_of({{"a", 5}}, 0, 1) == "f.json: sec.a = 5: must be in [0, 1]");
  CHECK(error_of({{"a", "x"}}, 0, 1) == "f.json: sec.a = \"x\": must be a number");
  CHECK(error_of({{"b", 1}}, 0, 1) == "f.json: sec.b = 1: unknown key (allowed here: a)");
  CHECK(error_of({{"a", 0.5}}, 0, 1).empty());
  std::string repeated;
  parse_json_checked(R"({"s": {"x": 1, "y": [1, {"x": 2, "x": 3}]}})", repeated);
  CHECK(repeated == "s.y.1.x");
}

TEST_CASE("the solver's step limits come from the scene's defaults", "[core][cpu]") {
  const Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.1,0.1,0.1]}, "sph": {"spacing": 0.01}})", "t.json");
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
  const Scene::Run run;
  CHECK(in.min_dt == float(run.min_dt));
  CHECK(in.max_dt == float(run.max_dt));
  CHECK(in.cfl == float(SphConfig{}.cfl));
  CHECK(s.sph.support_radius() == Approx(2.0 * s.sph.smoothing_ratio * s.sph.spacing).epsilon(1e-15));
  CHECK(s.sph.auto_boundary_layers() == 4);  // support 2h = 4 dx at h = 2 dx
}

TEST_CASE("Tait's density inverts its pressure, in float and double", "[core][cpu]") {
  const double rho0 = 1000, c0 = 20, b = tait_b(c0, rho0);
  CHECK(b == Approx(c0 * c0 * rho0 / 7.0));
  for (double rho : {990.0, 1000.0, 1003.0, 1030.0}) {
    const double p = tait_pressure(b, rho0, rho);
    CHECK(p == Approx(b * (std::pow(rho / rho0, 7.0) - 1.0)).epsilon(1e-12));
    CHECK(tait_density(b, rho0, p) == Approx(rho).epsilon(1e-12));
    const float pf = tait_pressure(float(b), float(rho0), float(rho));
    CHECK(tait_density(float(b), float(rho0), pf) == Approx(rho).epsilon(1e-5));
  }
}
