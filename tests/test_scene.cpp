// Scene parsing and validation: every bad value gets one message naming the
// file, the key and the value.
#include <filesystem>
#include <map>
#include <string>

#include "catch.h"
#include "helpers.h"

using namespace sphray;

namespace {

const char* kGood = R"({
  "name": "t", "tank": {"min": [0,0,0], "max": [1,0.5,0.5]},
  "fluid": [{"min": [0,0,0], "max": [0.2,0.5,0.3]}],
  "sph": {"spacing": 0.02}, "run": {"end_time": 0.1}
})";

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("a minimal scene parses with documented defaults", "[scene][cpu]") {
  const Scene s = parse_scene(kGood, "t.json");
  CHECK(s.sph.spacing == 0.02);
  CHECK(s.sph.rest_density == 1000);
  CHECK(s.sph.speed_of_sound == 0);  // auto
  CHECK(s.gravity.z == -9.81);
  CHECK(s.fluid.size() == 1);
  CHECK(s.run.end_time == 0.1);
}

TEST_CASE("--set overrides any value by its dotted path", "[scene][cpu]") {
  const Scene s = parse_scene(kGood, "t.json", {"sph.spacing=0.01", "run.end_time=2", "fluid.0.velocity=[1,0,0]", "name=x"});
  CHECK(s.sph.spacing == 0.01);
  CHECK(s.run.end_time == 2);
  CHECK(s.fluid[0].velocity.x == 1);
  CHECK(s.name == "x");
  CHECK(s.json["sph"]["spacing"] == 0.01);  // the scene as it ran
}

TEST_CASE("wall viscosity: sph.viscosity_alpha unless set apart, none on free-slip faces", "[scene][cpu]") {
  // Counts the wall particles by their viscosity coefficient.
  auto alphas = [](const Scene& s) {
    std::map<float, size_t> n;
    for (float a : make_solver_input(resolve_scene(s), PresenceMode::Off).boundary_alpha) ++n[a];
    return n;
  };
  const Scene same = parse_scene(kGood, "t.json", {"sph.viscosity_alpha=0.05"});
  const auto a = alphas(same);
  REQUIRE(a.size() == 1);
  CHECK(a.begin()->first == 0.05f);
  CHECK(a.begin()->second == make_solver_input(resolve_scene(same), PresenceMode::Off).boundary.size());

  const Scene apart = parse_scene(kGood, "t.json", {"sph.wall_viscosity_alpha=0.3", "tank.free_slip=[\"-y\",\"+y\"]"});
  CHECK(make_params(apart).viscosity_alpha == 0.02f);  // the fluid's own stays
  const auto b = alphas(apart);
  REQUIRE(b.size() == 2);
  CHECK(b.count(0.3f) == 1);
  CHECK(b.count(0.0f) == 1);  // the side walls, but not their edges with the floor
  CHECK(b.at(0.0f) > 0);
  CHECK(b.at(0.3f) > b.at(0.0f));

  CHECK(contains(test::scene_error(kGood, {"sph.wall_viscosity_alpha=-0.1"}), "sph.wall_viscosity_alpha = -0.1"));
}

TEST_CASE("bad scenes get a message naming file, key and value", "[scene][cpu]") {
  std::string e = test::scene_error(kGood, {"sph.spacingg=0.01"});
  CHECK(contains(e, "t.json"));
  CHECK(contains(e, "sph.spacingg"));
  CHECK(contains(e, "unknown key"));

  e = test::scene_error(kGood, {"sph.spacing=-0.1"});
  CHECK(contains(e, "sph.spacing = -0.1"));

  // Far from the origin, single-precision positions round distances to a
  // visible fraction of a spacing (docs/scenes.md: the dam break at 4 cm
  // moved 50,000 spacings out ends with 10% more kinetic energy; 10 km out,
  // 0.72% of particle-steps clamped to a wall). 16384 spacings at 2 cm: 327.68 m.
  const std::vector<std::string> far = {"tank.min=[326.5,0,0]", "tank.max=[327.5,0.5,0.5]", "fluid=[]"};
  CHECK(test::scene_error(kGood, far).empty());
  e = test::scene_error(kGood, {"tank.min=[0,-328,0]"});
  CHECK(contains(e, "t.json: tank.min = [0,-328,0]: lies 16400 particle spacings from the origin"));
  CHECK(contains(e, "move the tank nearer the origin"));
  CHECK(contains(test::scene_error(kGood, {"tank.max=[1e300,0.5,0.5]"}), "tank.max = [1e+300,0.5,0.5]: lies 5e+301 particle"));

  e = test::scene_error(kGood, {"sph.spacing=\"small\""});
  CHECK(contains(e, "sph.spacing"));
  CHECK(contains(e, "must be a number"));

  e = test::scene_error(kGood, {"sph.spacing=nan"});  // not JSON: read as a string, rejected as one
  CHECK(contains(e, "sph.spacing = \"nan\""));

  e = test::scene_error(kGood, {"fluid.0.max=[2,0.5,0.3]"});
  CHECK(contains(e, "fluid.0"));
  CHECK(contains(e, "outside the tank"));

  e = test::scene_error(kGood, {"tank.max=[1,0.5]"});
  CHECK(contains(e, "tank.max"));

  e = test::scene_error(kGood, {"tank.max=[-1,0.5,0.5]"});
  CHECK(contains(e, "greater than min"));

  e = test::scene_error(kGood, {"sph.kernel=\"gauss\""});
  CHECK(contains(e, "wendland_c2"));

  e = test::scene_error(kGood, {"tank.free_slip=[\"-w\"]"});
  CHECK(contains(e, "unknown face"));

  e = test::scene_error(kGood, {"nosuch.key=1"});
  CHECK(contains(e, "nosuch"));
  CHECK(contains(e, "unknown key"));

  CHECK(test::scene_error(R"({"tank": {"min": [0,0,0], "max": [1,1,1]}, "sph": {"spacing": 0.1}})", {"run.end_time=2"}).empty());
  // Output times closer than the smallest step allowed: every step would land below the floor.
  e = test::scene_error(kGood, {"run.output_interval=1e-9"});
  CHECK(contains(e, "run.output_interval = 1e-09: is below run.min_dt = 1e-08 s"));
  CHECK(test::scene_error(kGood, {"run.output_interval=1e-9", "run.min_dt=1e-10"}).empty());

  // PBF's single-precision poly6 overflows below a support of 55 um: refused
  // by sph.spacing, not run into infinite densities.
  const std::vector<std::string> small = {"sph.solver=pbf", "tank.max=[0.002,0.002,0.002]", "fluid.0.max=[0.001,0.001,0.001]"};
  auto with = [&](std::vector<std::string> v, std::string a) { v.push_back(a); return v; };
  e = test::scene_error(kGood, with(small, "sph.spacing=2e-5"));
  CHECK(contains(e, "sph.spacing = 2e-05: gives PBF a support of 4.2e-05 m"));
  CHECK(contains(e, "PBF needs sph.spacing >= 2.6"));
  CHECK(test::scene_error(kGood, with(small, "sph.spacing=2.7e-5")).empty());
  e = test::scene_error(kGood, with(with(small, "sph.spacing=2.7e-5"), "pbf.support=1.6"));
  CHECK(contains(e, "sph.spacing = 2.7e-05: gives PBF a support of 4.32e-05 m (pbf.support 1.6 spacings)"));
  CHECK(contains(e, "PBF needs sph.spacing >= 3.4"));
  CHECK(test::scene_error(kGood, {"sph.solver=wcsph", "tank.max=[0.002,0.002,0.002]", "fluid.0.max=[0.001,0.001,0.001]",
                                  "sph.spacing=2e-5"}).empty());

  e = test::scene_error(kGood, {"fluid.5.min=[0,0,0]"});  // one block: index 5 is past the end, not "fluid.1"
  CHECK(contains(e, "--set fluid.5.min"));
  CHECK(contains(e, "fluid has 1 element(s)"));
  CHECK(contains(e, "fluid.1 appends one"));
  CHECK(contains(test::scene_error(kGood, {"fluid.x.min=[0,0,0]"}), "'x' is not an index"));
  CHECK(contains(test::scene_error(kGood, {"fluid[0].min=[0,0,0]"}), "--set fluid[0].min: array elements are indexed with a dot: fluid.0.min"));
  e = test::scene_error(kGood, {"fluid.1.min=[0.5,0,0]"});  // appending a block asks for the rest of it
  CHECK(contains(e, "fluid.1"));
  CHECK(contains(e, "max"));
  CHECK(contains(e, "is required"));
  CHECK(parse_scene(kGood, "t.json", {"fluid.1={\"min\":[0.5,0,0],\"max\":[0.6,0.5,0.1]}"}).fluid.size() == 2);

  e = test::scene_error(kGood, {"gravity"});
  CHECK(contains(e, "key.path=value"));

  CHECK(contains(test::scene_error("{ \"tank\": "), "not valid JSON"));
  CHECK(contains(test::scene_error("[1,2]"), "must be a JSON object"));
  CHECK(contains(test::scene_error("{}"), "tank"));
}

TEST_CASE("the speed of sound: auto is 10x the flow speed the scene can reach, an explicit one below it is refused",
          "[scene][cpu]") {
  // kGood: a 0.3 m column standing on the floor under standard gravity.
  const double v_column = std::sqrt(9.81 * 0.3);
  CHECK(expected_flow_speed(parse_scene(kGood, "t.json")) == Approx(v_column).epsilon(1e-12));
  CHECK(make_params(parse_scene(kGood, "t.json")).speed_of_sound == Approx(10 * v_column).epsilon(1e-6));
  // A block held above the floor counts its fall: its top is 0.45 m up.
  CHECK(expected_flow_speed(parse_scene(kGood, "t.json", {"fluid.0.min=[0,0,0.4]", "fluid.0.max=[0.2,0.5,0.45]"})) ==
        Approx(std::sqrt(9.81 * 0.45)).epsilon(1e-12));
  // Without gravity, standard gravity stands in; a faster initial velocity wins.
  CHECK(expected_flow_speed(parse_scene(kGood, "t.json", {"gravity=[0,0,0]"})) == Approx(v_column).epsilon(1e-12));
  CHECK(expected_flow_speed(parse_scene(kGood, "t.json", {"fluid.0.velocity=[3,4,0]"})) == Approx(5.0).epsilon(1e-12));

  const std::string e = test::scene_error(kGood, {"sph.speed_of_sound=1.5"});  // sqrt(g H) = 1.72 m/s
  CHECK(contains(e, "sph.speed_of_sound = 1.5"));
  CHECK(contains(e, "supersonic"));
  CHECK(contains(e, "1.72 m/s"));
  CHECK(test::scene_error(kGood, {"sph.speed_of_sound=1.75"}).empty());
  CHECK(contains(test::scene_error(kGood, {"sph.speed_of_sound=5", "fluid.0.velocity=[6,0,0]"}), "supersonic"));
}

TEST_CASE("overlapping fluid blocks fill their union once, at its hydrostatic depth", "[scene][cpu]") {
  // Brute force over the generated particles: none closer than 3/4 spacing.
  auto closest = [](const std::vector<Float4>& p) {
    double d2 = 1e300;
    for (size_t a = 0; a < p.size(); ++a)
      for (size_t b = a + 1; b < p.size(); ++b) d2 = std::min(d2, double(length2(xyz(p[a]) - xyz(p[b]))));
    return std::sqrt(d2);
  };
  const double dx = 0.02;
  // The same block twice: the particles of one.
  const Scene twice = parse_scene(kGood, "t.json", {"fluid=[{\"min\":[0,0,0],\"max\":[0.2,0.5,0.3]},"
                                                    "{\"min\":[0,0,0],\"max\":[0.2,0.5,0.3]}]"});
  const SolverInput one = make_solver_input(resolve_scene(parse_scene(kGood, "t.json")), PresenceMode::Off);
  const SolverInput two = make_solver_input(resolve_scene(twice), PresenceMode::Off);
  REQUIRE(two.fluid_pos_rho.size() == one.fluid_pos_rho.size());
  for (size_t k = 0; k < one.fluid_pos_rho.size(); ++k)
    CHECK(length2(xyz(two.fluid_pos_rho[k]) - xyz(one.fluid_pos_rho[k])) == 0);

  // A column standing in a bed (an L in x-z), on one lattice: the union's
  // cells exactly, and the bed under the column at the column's depth.
  const Scene l = parse_scene(kGood, "t.json", {"fluid=[{\"min\":[0,0,0],\"max\":[1,0.5,0.1]},"
                                                "{\"min\":[0,0,0],\"max\":[0.2,0.5,0.4]}]"});
  const SolverInput in = make_solver_input(resolve_scene(l), PresenceMode::Off);
  CHECK(in.fluid_pos_rho.size() == 50 * 25 * 5 + 10 * 25 * 15);
  CHECK(closest(in.fluid_pos_rho) == Approx(dx).epsilon(1e-4));
  const double b = make_params(l).tait_b;
  for (const Float4& p : in.fluid_pos_rho) {
    const double top = p.x < 0.2 ? 0.4 : 0.1;
    const double rho = 1000 * std::pow(1 + 1000 * 9.81 * (top - p.z) / b, 1 / 7.0);
    REQUIRE(p.w == Approx(rho).epsilon(1e-6));
  }

  // Blocks on different lattices: nothing closer than 3/4 spacing, and the
  // union's volume filled to within a layer of particles along the seam.
  const Scene off = parse_scene(kGood, "t.json", {"fluid=[{\"min\":[0,0,0],\"max\":[0.2,0.5,0.3]},"
                                                  "{\"min\":[0.133,0,0],\"max\":[0.4,0.5,0.3]}]"});
  const SolverInput o = make_solver_input(resolve_scene(off), PresenceMode::Off);
  CHECK(closest(o.fluid_pos_rho) >= 0.75 * dx);
  const double union_cells = 0.4 * 0.5 * 0.3 / (dx * dx * dx);
  CHECK(std::abs(double(o.fluid_pos_rho.size()) - union_cells) <= 25 * 15);
}

TEST_CASE("a key given twice in one object is refused by its dotted path", "[scene][cpu]") {
  // JSON allows it and the parser keeps the last, so the first was ignored
  // silently (two "sph" sections ran with the second one's spacing).
  const std::string tank = R"("tank": {"min": [0,0,0], "max": [1,1,1]})";
  CHECK(test::scene_error("{" + tank + R"(, "sph": {"spacing": 0.1}, "sph": {"spacing": 0.2}})") ==
        "t.json: sph is given twice (JSON keeps only the last; give it once)");
  CHECK(contains(test::scene_error("{" + tank + R"(, "sph": {"spacing": 0.1, "rest_density": 1000, "spacing": 0.2}})"),
                 "t.json: sph.spacing is given twice"));
  // inside an array: the element's index (arrays count nested objects and scalars alike)
  CHECK(contains(test::scene_error("{" + tank + R"(, "sph": {"spacing": 0.1}, "fluid": [
      {"min": [0,0,0], "max": [0.5,0.5,0.5]},
      {"min": [0.5,0,0], "max": [1,0.5,0.5], "velocity": [0,0,0], "max": [1,1,1]}]})"),
                 "t.json: fluid.1.max is given twice"));
  CHECK(contains(test::scene_error(kGood, {R"(fluid.0={"min":[0,0,0],"max":[0.1,0.1,0.1],"min":[0,0,0]})"}),
                 "--set fluid.0: the value names 'min' twice"));
  // the same key in different objects is no repeat
  CHECK(test::scene_error("{" + tank + R"(, "sph": {"spacing": 0.1}, "fluid": [
      {"min": [0,0,0], "max": [0.5,0.5,0.5]}, {"min": [0.5,0,0], "max": [1,0.5,0.5]}]})").empty());
}

TEST_CASE("a missing scene file is a clear error", "[scene][cpu]") {
  CHECK_THROWS_AS(load_scene("/nonexistent/scene.json"), SceneError);
}

TEST_CASE("a scene too large for memory is refused before allocating", "[scene][cpu]") {
  const Scene s = parse_scene(kGood, "t.json", {"tank.max=[16,16,16]", "fluid.0.max=[16,16,8]", "sph.spacing=0.001"});
  std::string e;
  try {
    check_fits(resolve_scene(s), Backend::Cpu);
  } catch (const SceneError& x) {
    e = x.what();
  }
  CHECK(contains(e, "sph.spacing"));
  CHECK(contains(e, "Raise sph.spacing"));
}

TEST_CASE("the shipped scenes all parse", "[scene][cpu]") {
  int n = 0;
  for (const auto& e : std::filesystem::recursive_directory_iterator(test::source_path("scenes"))) {
    if (e.path().extension() != ".json") continue;
    INFO(e.path().string());
    CHECK_NOTHROW(load_scene(e.path().string()));
    ++n;
  }
  CHECK(n >= 18);  // the stress suite's ten among them
}

TEST_CASE("the main job's scene is the dam break, under PBF with Zhu & Bridson's surface", "[scene][cpu]") {
  const Scene reference = load_scene(test::source_path("scenes/dam_break.json"));
  const Scene watched = load_scene(test::source_path("scenes/dam_break_realtime.json"));
  for (const char* key : {"tank", "fluid", "gravity", "run"}) {
    INFO(key);
    CHECK(watched.json.at(key) == reference.json.at(key));
  }
  CHECK(watched.sph.solver == SolverKind::Pbf);
  CHECK(reference.sph.solver == SolverKind::Wcsph);
  CHECK(watched.field.kernel == FieldKernel::ZhuBridson);
  CHECK(watched.field.builder == FieldKind::Gather);
  CHECK_FALSE(watched.field.every_frame);  // built where frames or the viewer draw it
  CHECK(watched.sph.spacing == Approx(0.00432));
}

TEST_CASE("a scene sized for a GPU gets a note naming a spacing the CPU can play", "[scene][cpu]") {
  const Scene watched = load_scene(test::source_path("scenes/dam_break_realtime.json"));
  const ResolvedScene r = resolve_scene(watched);
  REQUIRE(r.size.fluid > kCpuLargeScene);
  CHECK(cpu_scale_note(r, Backend::Cuda).empty());
  const std::string note = cpu_scale_note(r, Backend::Cpu);
  INFO(note);
  CHECK(test::has(note, std::to_string(r.size.fluid) + " fluid particles on the CPU backend"));
  // The spacing it names, counted independently: about the target.
  const std::string key = "sph.spacing=";
  const size_t at = note.find(key);
  REQUIRE(at != std::string::npos);
  const double spacing = std::stod(note.substr(at + key.size()));
  CHECK(spacing == Approx(0.015));  // the README's CPU fallback for this scene
  const size_t n = measure_scene(load_scene(test::source_path("scenes/dam_break_realtime.json"),
                                            {"sph.spacing=" + std::to_string(spacing)})).fluid;
  CHECK(n <= kCpuSceneTarget * 11 / 10);
  CHECK(n >= kCpuSceneTarget / 2);
  CHECK(test::has(note, "gives " + std::to_string(n) + " "));
  // At that spacing no note.
  CHECK(cpu_scale_note(resolve_scene(load_scene(test::source_path("scenes/dam_break_realtime.json"),
                                                {"sph.spacing=0.015"})),
                       Backend::Cpu)
            .empty());
}
