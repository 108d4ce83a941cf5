// Triangle-mesh obstacles in scenes: bad meshes refused by key and file, the
// setup's fluid and wall particles against the mesh, no particle through a
// thin plate, and the buoyant force of the pressure on a submerged box.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "catch.h"
#include "helpers.h"
#include "io/metrics.h"
#include "mesh/bvh.h"
#include "pipeline/setup.h"
#include "sph/skin.h"

using namespace sphray;
using test::has;

namespace {

// A unit cube [0, 1]^3 as an OBJ file (placed by scale and translate).
std::string unit_box_obj() {
  const std::string path = test::tmp_dir() + "/unit_box.obj";
  write_obj(box_mesh({{0, 0, 0}, {1, 1, 1}}), path);
  return path;
}

std::string with_obstacle(const std::string& obstacle, const std::string& sph = R"({"spacing": 0.01})") {
  return R"({"tank": {"min": [0, 0, 0], "max": [0.4, 0.1, 0.3]},
    "fluid": [{"min": [0, 0, 0], "max": [0.15, 0.1, 0.25]}],
    "obstacles": [)" + obstacle + R"(], "sph": )" + sph + R"(, "run": {"end_time": 0.3, "output_interval": 0.1}})";
}

std::string plate(const std::string& mesh, double dx) {
  // One spacing thick, from wall to wall and floor to lid: it seals the column's side.
  std::ostringstream os;
  os << R"({"mesh": ")" << mesh << R"(", "scale": [)" << dx << R"(, 0.1, 0.3], "translate": [0.25, 0, 0]})";
  return os.str();
}

}  // namespace

TEST_CASE("bad obstacles are refused naming the key, the file and the problem", "[mesh][cpu]") {
  const std::string box = unit_box_obj();
  const std::string dir = test::tmp_dir();
  std::ofstream(dir + "/nan.obj") << "v 0 0 0\nv 1 0 nan\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n";
  std::ofstream(dir + "/empty.obj") << "# no faces\nv 0 0 0\n";
  std::ofstream(dir + "/open.obj") << "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n";
  std::string e = test::scene_error(with_obstacle(R"({"mesh": ")" + dir + R"(/missing.obj"})"));
  CHECK((has(e, "obstacles.0.mesh") && has(e, "missing.obj") && has(e, "cannot open")));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + dir + R"(/nan.obj", "scale": 0.05})"));
  CHECK((has(e, "nan.obj") && has(e, "not finite")));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + dir + R"(/empty.obj"})"));
  CHECK((has(e, "empty.obj") && has(e, "no triangles")));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + dir + R"(/open.obj"})"));
  CHECK((has(e, "open.obj") && has(e, "not closed")));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + box + R"(", "scale": 0})"));
  CHECK(has(e, "obstacles.0.scale"));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + box + R"(", "scale": [0.1, -0.1, 0.1]})"));
  CHECK((has(e, "obstacles.0.scale") && has(e, "> 0")));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + box + R"(", "scale": 0.1, "translate": [0.35, 0, 0]})"));
  CHECK((has(e, "unit_box.obj") && has(e, "crosses the tank walls")));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + box + R"(", "scael": 0.1})"));
  CHECK(has(e, "scael"));
  e = test::scene_error(with_obstacle(R"({"scale": 0.1})"));
  CHECK((has(e, "obstacles.0.mesh") && has(e, "required")));
  std::string nine;
  for (int k = 0; k < 9; ++k) nine += std::string(k ? "," : "") + R"({"mesh": ")" + box + R"(", "scale": 0.01})";
  CHECK(has(test::scene_error(with_obstacle(nine)), "at most 8 obstacles"));
  // Too thin for the wall particles of WCSPH: said before the run.
  const Scene thin = parse_scene(with_obstacle(plate(box, 0.004)), "t.json");
  try {
    make_solver_input(resolve_scene(thin), PresenceMode::Off);
    FAIL("a plate thinner than the spacing was taken");
  } catch (const SceneError& err) {
    CHECK(has(err.what(), "thinner than the spacing"));
  }
}

TEST_CASE("a bad mesh ends sphray run with exit code 2 and the file's name", "[mesh][cpu]") {
  const std::string dir = test::tmp_dir();
  std::ofstream(dir + "/obst_scene.json") << with_obstacle(R"({"mesh": "no_such_mesh.obj"})");
  const auto r = test::run_cli("run " + dir + "/obst_scene.json --backend cpu --quiet");
  CHECK(r.code == 2);
  CHECK(has(r.output, dir + "/no_such_mesh.obj"));  // resolved against the scene's folder
  // The scene as it runs (what an export carries) names the mesh absolutely.
  write_obj(box_mesh({{0, 0, 0}, {1, 1, 1}}), dir + "/here.obj");
  std::ofstream(dir + "/rel_scene.json") << with_obstacle(R"({"mesh": "here.obj", "scale": 0.05})");
  const Scene s = load_scene(dir + "/rel_scene.json");
  CHECK(s.obstacles[0].path == dir + "/here.obj");
  const std::string named = s.json["obstacles"][0]["mesh"];
  CHECK(std::filesystem::path(named).is_absolute());
  CHECK(std::filesystem::equivalent(named, dir + "/here.obj"));
}

TEST_CASE("the fluid keeps out of an obstacle and WCSPH's wall particles fill its skin", "[mesh][cpu]") {
  // A 6 cm cube in the middle of a pool, its faces between lattice planes.
  const std::string text = R"({"tank": {"min": [0, 0, 0], "max": [0.2, 0.2, 0.2]},
    "fluid": [{"min": [0, 0, 0], "max": [0.2, 0.2, 0.16]}],
    "obstacles": [{"mesh": ")" + unit_box_obj() + R"(", "scale": 0.06, "translate": [0.07, 0.07, 0.05]}],
    "sph": {"spacing": 0.01}})";
  const ResolvedScene r = resolve_scene(parse_scene(text, "t.json"));
  const SolverInput in = make_solver_input(r, PresenceMode::Off);
  REQUIRE(in.obstacles.size() == 1);
  // 20 x 20 x 16 lattice points less the 6 x 6 x 6 inside the cube.
  CHECK(in.fluid_pos_rho.size() == 20 * 20 * 16 - 6 * 6 * 6);
  const Box cube{{0.07, 0.07, 0.05}, {0.13, 0.13, 0.11}};
  size_t in_cube = 0;
  for (const Float4& b : in.boundary) {
    const bool inside = b.x > cube.min.x && b.x < cube.max.x && b.y > cube.min.y && b.y < cube.max.y &&
                        b.z > cube.min.z && b.z < cube.max.z;
    in_cube += inside;
  }
  // The cube is 6 points wide, the skin (sph.boundary_layers deep) reaches its middle: all 216.
  CHECK(in_cube == 216);
  for (const Float4& f : in.fluid_pos_rho) {
    const bool near = f.x > cube.min.x - 0.004 && f.x < cube.max.x + 0.004 && f.y > cube.min.y - 0.004 &&
                      f.y < cube.max.y + 0.004 && f.z > cube.min.z - 0.004 && f.z < cube.max.z + 0.004;
    CHECK_FALSE(near);
  }
}

TEST_CASE("no particle passes a plate one spacing thick, at three resolutions and under every solver", "[mesh][cpu]") {
  const std::string box = unit_box_obj();
  struct Case { double dx; const char* sph; };
  const Case cases[] = {{0.02, R"({"spacing": 0.02})"}, {0.015, R"({"spacing": 0.015})"}, {0.01, R"({"spacing": 0.01})"},
                        {0.01, R"({"spacing": 0.01, "solver": "pbf"})"}, {0.01, R"({"spacing": 0.01, "solver": "dfsph"})"}};
  for (const Case& c : cases) {
    INFO("sph " << c.sph);
    const Scene s = parse_scene(with_obstacle(plate(box, c.dx), c.sph), "t.json");
    const ResolvedScene r = resolve_scene(s);
    auto solver = make_cpu_solver(make_solver_input(r, PresenceMode::Off));
    const size_t n = solver->num_fluid();
    size_t leaked = 0, steps_seen = 0;
    double front = 0;
    while (solver->time() < 0.3 - 1e-12) {
      solver->step(0.3);
      if (++steps_seen % 10 != 0) continue;
      for (const Vec3f& p : solver->download().pos) {
        leaked += p.x > 0.25;
        front = std::max(front, double(p.x));
      }
    }
    CHECK(solver->num_fluid() == n);
    CHECK(leaked == 0);
    CHECK(front > 0.24);  // the liquid did reach the plate
  }
}

namespace {

// A 6 cm cube in the middle of a 16 cm deep pool (its faces between lattice
// planes), at rest from the hydrostatic start: the pressure integrated over
// the cube's faces (obstacle_force), averaged over t = 0.1 .. 0.2 s. WCSPH's
// pressure is its state's (Tait), sampled every 0.01 s; DFSPH's its solve's
// (Solver::pressures), sampled after every full step (a step shortened to
// land on a time stops its solve at the same density tolerance, which is a
// larger pressure error at the shorter step: p ~ error / dt^2).
Vec3d buoyancy(Backend backend, const std::string& solver_kind, double& archimedes) {
  const std::string text = R"({"tank": {"min": [0, 0, 0], "max": [0.2, 0.2, 0.2]},
    "fluid": [{"min": [0, 0, 0], "max": [0.2, 0.2, 0.16]}],
    "obstacles": [{"mesh": ")" + unit_box_obj() + R"(", "scale": 0.06, "translate": [0.07, 0.07, 0.05]}],
    "sph": {"spacing": 0.01, "solver": ")" + solver_kind + R"("}})";
  const Scene s = parse_scene(text, "t.json");
  const ResolvedScene r = resolve_scene(s);
  const SolverInput in = make_solver_input(r, PresenceMode::Off);
  auto solver = backend == Backend::Cuda ? make_cuda_solver(in) : make_cpu_solver(in);
  const SphParams& prm = r.params;
  const SmoothingKernel<double> k = SmoothingKernel<double>::make(prm.kernel.type, prm.kernel.h);
  archimedes = 1000.0 * 9.81 * 0.06 * 0.06 * 0.06;
  Vec3d mean{0, 0, 0};
  int samples = 0;
  test::run_until(*solver, 0.1);
  if (solver_kind != "wcsph") {
    while (solver->time() < 0.2 - 1e-12) {
      solver->step(0.2);
      if (solver->time() >= 0.2 - 1e-12) break;
      const ObstacleForce f = obstacle_force(s.obstacles[0].mesh, solver->download(), solver->pressures(), k, s.gravity,
                                             s.sph.spacing);
      CHECK(f.wetted == Approx(1.0));
      mean += f.force;
      ++samples;
    }
    return mean * (1.0 / samples);
  }
  for (double t = 0.1; t <= 0.2 + 1e-9; t += 0.01) {
    test::run_until(*solver, t);
    const HostParticles h = solver->download();
    std::vector<float> p(h.density.size());
    for (size_t i = 0; i < p.size(); ++i) p[i] = tait_pressure(prm, h.density[i]);
    const ObstacleForce f = obstacle_force(s.obstacles[0].mesh, h, p, k, s.gravity, s.sph.spacing);
    CHECK(f.wetted == Approx(1.0));
    mean += f.force;
    ++samples;
  }
  return mean * (1.0 / samples);
}

// The buoyancy check of one backend and solver: upward rho g V within 2%, no sideways force.
void check_buoyancy(Backend backend, const std::string& solver_kind) {
  double archimedes = 0;
  const Vec3d f = buoyancy(backend, solver_kind, archimedes);
  INFO(solver_kind << ": force " << f.x << ", " << f.y << ", " << f.z << " N; rho g V = " << archimedes << " N");
  CHECK(f.z == Approx(archimedes).epsilon(0.02));
  CHECK(std::abs(f.x) < 0.02 * archimedes);
  CHECK(std::abs(f.y) < 0.02 * archimedes);
}

}  // namespace

TEST_CASE("a box held under water feels the buoyant force rho g V through the wall pressure", "[mesh][cpu]") {
  check_buoyancy(Backend::Cpu, "wcsph");
  check_buoyancy(Backend::Cpu, "dfsph");
}

TEST_CASE("cuda: a box held under water feels the buoyant force rho g V", "[gpu]") {
  check_buoyancy(Backend::Cuda, "wcsph");
  check_buoyancy(Backend::Cuda, "dfsph");
}

// A still pool over a submerged cube, after 0.3 s: the first layer of
// liquid over the cube's top face and over the tank's floor. Every solver's
// walls keep it off the face (the lattice starts it half a spacing above),
// at the rest density: WCSPH's wall particles as on the
// floor; PBF's and DFSPH's (mesh_walls.h) within 0.1 to 0.6 spacings (PBF's
// one-sided constraint lets the column settle onto every wall, softer
// against static wall particles than against its moving mirror images, and
// DFSPH's first layers above the cube pack more densely than the start's
// lattice, at the same density). With the collision test alone the liquid
// came down to the face.
TEST_CASE("a pool rests on a submerged mesh as on the tank's floor, under every solver", "[mesh][cpu]") {
  for (const char* kind : {"wcsph", "pbf", "dfsph"}) {
    INFO(kind);
    const std::string text = R"({"tank": {"min": [0, 0, 0], "max": [0.2, 0.2, 0.2]},
      "fluid": [{"min": [0, 0, 0], "max": [0.2, 0.2, 0.16]}],
      "obstacles": [{"mesh": ")" + unit_box_obj() + R"(", "scale": 0.06, "translate": [0.07, 0.07, 0.05]}],
      "sph": {"spacing": 0.01, "solver": ")" + std::string(kind) + R"("}})";
    const ResolvedScene r = resolve_scene(parse_scene(text, "t.json"));
    auto solver = make_cpu_solver(make_solver_input(r, PresenceMode::Off));
    const size_t n = solver->num_fluid();
    test::run_until(*solver, 0.3);
    const HostParticles h = solver->download();
    // The first layer: within a spacing of the face, over the cube's top
    // (away from its edges) and over the floor (away from the cube and the walls).
    double gap_box = 0, gap_floor = 0, rho_box = 0, rho_floor = 0, low_box = 1;
    int n_box = 0, n_floor = 0;
    for (size_t i = 0; i < h.pos.size(); ++i) {
      const Vec3f x = h.pos[i];
      const bool over_box = x.x > 0.08f && x.x < 0.12f && x.y > 0.08f && x.y < 0.12f && x.z > 0.1f;
      const bool over_floor = (x.x < 0.05f || x.x > 0.15f || x.y < 0.05f || x.y > 0.15f) && x.x > 0.02f && x.x < 0.18f &&
                              x.y > 0.02f && x.y < 0.18f;
      if (over_box) low_box = std::min(low_box, double(x.z) - 0.11);
      if (over_box && x.z < 0.12f) gap_box += x.z - 0.11, rho_box += h.density[i], ++n_box;
      if (over_floor && x.z < 0.01f) gap_floor += x.z, rho_floor += h.density[i], ++n_floor;
    }
    REQUIRE(n_box > 0);
    REQUIRE(n_floor > 0);
    gap_box /= n_box, gap_floor /= n_floor, rho_box /= n_box, rho_floor /= n_floor;
    INFO("first layer over the cube: " << n_box << " particles " << gap_box << " m above it (lowest " << low_box
                                       << " m), density " << rho_box << "; over the floor: " << n_floor << " particles "
                                       << gap_floor << " m, density " << rho_floor);
    CHECK(solver->num_fluid() == n);
    // Against the collision test alone the first layer came down to the face (1e-4 m).
    CHECK(low_box > 0.001);
    CHECK(gap_box > 0.001);
    CHECK(gap_box < 0.006);
    if (std::string(kind) == "wcsph") CHECK(gap_box == Approx(gap_floor).margin(0.001));
    // The incompressible solvers hold the rest density (PBF within its depth
    // error, 1% by default, pbf.h; the floor's first layer lies deeper).
    else CHECK(rho_box == Approx(1000.0).epsilon(0.01));
  }
}

TEST_CASE("a gauge reads the depth of a still pool and nothing where it is dry", "[mesh][cpu]") {
  const std::string text = R"({"tank": {"min": [0, 0, 0], "max": [0.4, 0.2, 0.3]},
    "fluid": [{"min": [0, 0, 0], "max": [0.2, 0.2, 0.12]}],
    "gauges": [{"name": "wet", "at": [0.1, 0.1]}, {"name": "dry", "at": [0.3, 0.1]}],
    "sph": {"spacing": 0.01}})";
  const Scene s = parse_scene(text, "t.json");
  REQUIRE(s.gauges.size() == 2);
  const ResolvedScene r = resolve_scene(s);
  const SolverInput in = make_solver_input(r, PresenceMode::Off);
  HostParticles h;
  for (const Float4& p : in.fluid_pos_rho) h.pos.push_back({p.x, p.y, p.z});
  const SmoothingKernel<double> k = SmoothingKernel<double>::make(r.params.kernel.type, r.params.kernel.h);
  const double V = 1e-6;
  // The lattice's top layer sits half a spacing under 0.12 m: the kernel sum falls through 1/2 at the top.
  CHECK(water_height(h, 0.1, 0.1, k, V, 0.0, 0.3, 0.01) == Approx(0.12).margin(0.0026));
  CHECK(water_height(h, 0.3, 0.1, k, V, 0.0, 0.3, 0.01) == 0.0);
  // Deeper water reads deeper, by the added depth.
  const double two = water_height(h, 0.1, 0.1, k, V, 0.0, 0.3, 0.01);
  for (auto& p : h.pos) p.z += 0.05f;  // the whole pool lifted
  CHECK(water_height(h, 0.1, 0.1, k, V, 0.0, 0.3, 0.01) == Approx(two + 0.05).margin(0.0026));
  // Bad gauges are refused by key.
  CHECK(has(test::scene_error(text, {"gauges.1.at=[0.5, 0.1]"}), "gauges.1.at"));
  CHECK(has(test::scene_error(text, {"gauges.1.name=wet"}), "earlier gauge"));
  CHECK(has(test::scene_error(text, {"gauges.0.at=3"}), "gauges.0.at"));
}

TEST_CASE("a prescribed motion turns about its pivot and moves by its amplitude", "[mesh][cpu]") {
  Motion m;
  m.omega = float(2 * M_PI / 2.0);  // period 2 s
  m.translate = {0.1f, 0, 0};
  m.rotate = {0, 0, float(M_PI / 6)};  // 30 degrees about z
  m.pivot = {1, 1, 0};
  const RigidFrame f0 = m.at(0.0f), f = m.at(0.5f);  // t = T/4: sin = 1
  const Vec3f p{2, 1, 0.5f};
  CHECK(length(f0.to_world(p) - p) < 1e-6f);
  // The pivot moves by the translation only.
  CHECK(length(f.to_world(m.pivot) - (m.pivot + m.translate)) < 1e-6f);
  // A point 1 m off the pivot along x turns by 30 degrees about z.
  const Vec3f q = f.to_world(p);
  CHECK(q.x == Approx(1.0 + std::cos(M_PI / 6) + 0.1).margin(1e-5));
  CHECK(q.y == Approx(1.0 + std::sin(M_PI / 6)).margin(1e-5));
  CHECK(q.z == Approx(0.5).margin(1e-6));
  CHECK(length(f.to_body(q) - p) < 1e-5f);
  // The same rotation as the placement's (mesh.h), at the same angles.
  const auto R = rotation_rows({0, 0, 30});
  CHECK(f.r[0].x == Approx(R[0].x).margin(1e-6));
  CHECK(f.r[0].y == Approx(R[0].y).margin(1e-6));
  CHECK(f.r[1].x == Approx(R[1].x).margin(1e-6));
}

TEST_CASE("a moving plate pushes a resting particle ahead of it at its own speed", "[mesh][cpu]") {
  const TriangleMesh plate = box_mesh({{0.1, -0.5, -0.5}, {0.12, 0.5, 0.5}});
  const MeshInput in = mesh_input(plate);
  const auto bvh = make_cpu_bvh(in.vertices, in.indices);
  Obstacles obs;
  obs.mesh[0] = bvh->view();
  obs.motion[0].omega = float(2 * M_PI);  // period 1 s, 0.05 m amplitude along x: 0.314 m/s at t = 0
  obs.motion[0].translate = {0.05f, 0, 0};
  obs.count = 1;
  obs.offset = 1e-4f;
  // A particle at rest 1 mm ahead of the plate's face at x = 0.12; the plate moves 1.57 mm in 5 ms.
  Vec3f to{0.121f, 0.0f, 0.0f};
  const Stop stop = stop_at_obstacles(obs, {0.121f, 0.0f, 0.0f}, to, 0.0f, 0.005f);
  REQUIRE(stop.hit());
  CHECK(stop.normal.x == Approx(1.0f));
  const double face = 0.12 + 0.05 * std::sin(2 * M_PI * 0.005);
  CHECK(to.x == Approx(face + 1e-4).margin(1e-6));
  CHECK(stop.wall_velocity.x == Approx(0.05 * std::sin(2 * M_PI * 0.005) / 0.005).epsilon(1e-3));
  const Vec3f vel = velocity_after({0, 0.2f, 0}, stop);  // the normal part becomes the plate's, the tangential stays
  CHECK(vel.x == Approx(stop.wall_velocity.x));
  CHECK(vel.y == Approx(0.2f));
  // Farther ahead than the plate moves: untouched.
  to = {0.125f, 0.0f, 0.0f};
  CHECK_FALSE(stop_at_obstacles(obs, {0.125f, 0.0f, 0.0f}, to, 0.0f, 0.005f).hit());
  CHECK(to.x == 0.125f);
}

namespace {

std::string wave_tank(const std::string& solver, double amplitude = 0.03) {
  return R"({"tank": {"min": [0, 0, 0], "max": [1.0, 0.1, 0.4]},
    "fluid": [{"min": [0.08, 0, 0], "max": [1.0, 0.1, 0.16]}],
    "obstacles": [{"mesh": ")" + unit_box_obj() + R"(", "scale": [0.02, 0.1, 0.3], "translate": [0.05, 0, 0],
                   "motion": {"period": 1.0, "translate": [)" + std::to_string(amplitude) + R"(, 0, 0]}}],
    "sph": {"spacing": 0.02, "solver": ")" + solver + R"("}, "run": {"end_time": 0.8, "output_interval": 0.1}})";
}

// Runs the wave tank to 0.8 s: particles found inside the paddle's pose of
// the moment (every fifth step), and the kinetic energy at the end.
double run_wave_tank(const std::string& solver, double amplitude, size_t& inside, size_t& lost,
                     Backend backend = Backend::Cpu) {
  const Scene s = parse_scene(wave_tank(solver, amplitude), "t.json");
  const ResolvedScene r = resolve_scene(s);
  const SolverInput in = make_solver_input(r, PresenceMode::Off);
  auto sv = backend == Backend::Cuda ? make_cuda_solver(in) : make_cpu_solver(in);
  const size_t n = sv->num_fluid();
  const Motion& m = s.obstacles[0].motion;
  int k = 0;
  while (sv->time() < 0.8 - 1e-12) {
    sv->step(0.8);
    if (++k % 5 != 0) continue;
    const RigidFrame f = m.at(float(sv->time()));
    for (const Vec3f& p : sv->download().pos) {
      const Vec3f b = f.to_body(p);  // the paddle's own frame: its box at t = 0
      inside += b.x > 0.05f + 1e-4f && b.x < 0.07f - 1e-4f && b.z < 0.3f - 1e-4f;
    }
  }
  lost = n - sv->num_fluid();
  return kinetic_energy(sv->download(), r.params.particle_mass);
}

// The piston against the paddle held still, on one solver and backend: no
// particle inside the paddle or lost in either run, and the piston (3 cm,
// 1 s: up to 0.19 m/s) puts energy into the liquid that a paddle held still
// does not.
void check_piston(const std::string& solver, Backend backend) {
  INFO(solver);
  size_t inside = 0, lost = 0, inside_still = 0, lost_still = 0;
  const double moving = run_wave_tank(solver, 0.03, inside, lost, backend);
  const double still = run_wave_tank(solver, 0.0, inside_still, lost_still, backend);
  INFO("kinetic energy at 0.8 s: " << moving << " J with the piston, " << still << " J with it still");
  CHECK(inside == 0);
  CHECK(inside_still == 0);
  CHECK(lost == 0);
  CHECK(lost_still == 0);
  CHECK(moving > 2.0 * still);
}

}  // namespace

TEST_CASE("a piston paddle drives the liquid and no particle enters it, under every solver", "[mesh][cpu]") {
  for (const char* solver : {"wcsph", "pbf", "dfsph"}) check_piston(solver, Backend::Cpu);
  const Scene s = parse_scene(wave_tank("wcsph"), "t.json");
  REQUIRE(s.obstacles[0].motion.moves());
  // WCSPH's paddle has wall particles, marked with their obstacle.
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
  REQUIRE(in.boundary_obstacle.size() == in.boundary.size());
  size_t paddle = 0;
  for (const uint8_t o : in.boundary_obstacle) paddle += o == 0;
  CHECK(paddle == 5 * 15);  // one layer (2 cm thick at 2 cm spacing), 5 across, 15 up
  // A motion that takes the paddle through the wall is refused before the run.
  const std::string e = test::scene_error(wave_tank("wcsph"), {"obstacles.0.motion.translate=[-0.08, 0, 0]"});
  CHECK((has(e, "obstacles.0.motion") && has(e, "out of the tank")));
  CHECK(has(test::scene_error(wave_tank("wcsph"), {"obstacles.0.motion.period=0"}), "obstacles.0.motion.period"));
  CHECK(has(test::scene_error(wave_tank("wcsph"), {"obstacles.0.motion.rotate=[0, 120, 0]"}), "90 degrees"));
}

TEST_CASE("cuda: a piston paddle drives the liquid and no particle enters it", "[gpu]") {
  for (const char* solver : {"wcsph", "pbf", "dfsph"}) check_piston(solver, Backend::Cuda);
}

namespace {

// Linear wave-maker theory for a flap hinged at the floor (Biesel & Suquet
// 1951, as in Dean & Dalrymple 1991): the progressive waves' height per unit
// of the flap's stroke at the still water level, in water `depth` deep
// driven at `period`, and their group speed; kh from w^2 h / g = kh tanh kh
// by bisection (its left side grows with kh).
struct FlapWaves {
  double height_over_stroke, group_speed;
};
FlapWaves flap_waves(double depth, double period, double g) {
  const double w = 2.0 * M_PI / period, target = w * w * depth / g;
  double lo = 0.0, hi = std::max(target, std::sqrt(target)) + 1.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (mid * std::tanh(mid) < target ? lo : hi) = mid;
  }
  const double kh = 0.5 * (lo + hi), k = kh / depth;
  const double hs =
      4.0 * (std::sinh(kh) / kh) * (kh * std::sinh(kh) - std::cosh(kh) + 1.0) / (std::sinh(2.0 * kh) + 2.0 * kh);
  return {hs, 0.5 * (w / k) * (1.0 + 2.0 * kh / std::sinh(2.0 * kh))};
}

}  // namespace

TEST_CASE("flap wave-maker theory: its shallow and deep water limits", "[mesh][cpu]") {
  // Shallow water: H / S = kh / 2 (the flap's mean displacement is half its
  // stroke, and a piston's waves are kh S), group speed sqrt(g h); deep
  // water: H / S = 2 - 2 / kh, group speed half of g T / (2 pi).
  const double g = 9.81;
  const FlapWaves shallow = flap_waves(0.01, 20.0, g);
  const double kh_shallow = 2.0 * M_PI / 20.0 * 0.01 / std::sqrt(g * 0.01);
  CHECK(shallow.height_over_stroke == Approx(kh_shallow / 2).epsilon(1e-3));
  CHECK(shallow.group_speed == Approx(std::sqrt(g * 0.01)).epsilon(1e-3));
  const FlapWaves deep = flap_waves(10.0, 1.0, g);
  const double k_deep = std::pow(2.0 * M_PI, 2) / g;
  CHECK(deep.height_over_stroke == Approx(2.0 - 2.0 / (k_deep * 10.0)).epsilon(1e-6));
  CHECK(deep.group_speed == Approx(0.5 * g / (2.0 * M_PI)).epsilon(1e-6));
}

TEST_CASE("cuda: the wave tank's flap makes the waves of linear wave-maker theory", "[gpu]") {
  // scenes/wave_tank.json (1 cm, 268,200 particles) under DFSPH at water's
  // viscosity: the gauge at x = 1 m while only the generated waves pass it,
  // from the wave train's arrival (at the group speed, from the flap's face)
  // plus a period until the wave reflected by the far wall returns. Its
  // crest to trough within 10% of the theory's 53.5 mm (measured on the
  // H200: 52.5 mm; at the default viscosity 40 mm, docs/validation.md).
  const Scene s = load_scene(test::source_path("scenes/wave_tank.json"), {"sph.solver=dfsph", "dfsph.viscosity=1e-6"});
  const ResolvedScene r = resolve_scene(s);
  auto sv = make_cuda_solver(make_solver_input(r, PresenceMode::Off));
  const size_t n = sv->num_fluid();
  const Motion& m = s.obstacles[0].motion;
  const double depth = s.fluid[0].box.max.z - s.tank.min.z, period = 2.0 * M_PI / m.omega;
  const double stroke = 2.0 * depth * std::tan(std::abs(m.rotate.y));
  double face = -1e30;
  for (const Vec3d& v : s.obstacles[0].mesh.vertices) face = std::max(face, v.x);
  const FlapWaves theory = flap_waves(depth, period, 9.81);
  const double H = theory.height_over_stroke * stroke;
  const Gauge& gauge = s.gauges[0];
  const double t0 = (gauge.x - face) / theory.group_speed + period;
  const double t1 = (2.0 * s.tank.max.x - face - gauge.x) / theory.group_speed;
  REQUIRE(t1 - t0 > period);
  const SmoothingKernel<double> kernel = SmoothingKernel<double>::make(r.params.kernel.type, r.params.kernel.h);
  const double volume = double(r.params.particle_mass) / double(r.params.rest_density);
  double lowest = 1e30, highest = -1e30;
  for (double t = s.run.output_interval; t < t1 + 1e-9; t += s.run.output_interval) {
    while (sv->time() < t - 1e-9) sv->step(t);
    if (sv->time() < t0) continue;
    const double height =
        water_height(sv->download(), gauge.x, gauge.y, kernel, volume, s.tank.min.z, s.tank.max.z, s.sph.spacing);
    lowest = std::min(lowest, height);
    highest = std::max(highest, height);
  }
  INFO("theory " << H << " m, crest to trough " << highest - lowest << " m over " << t0 << " - " << t1 << " s");
  CHECK(std::abs(highest - lowest - H) < 0.1 * H);
  CHECK(sv->num_fluid() == n);
}

TEST_CASE("bad skins are refused naming the key and the problem", "[mesh][cpu]") {
  const std::string box = unit_box_obj();
  const std::string torus = test::tmp_dir() + "/torus.obj";
  write_obj(test::torus_mesh("torus"), torus);
  auto skinned = [&](const std::string& mesh, const std::string& skin, const std::string& sph = R"({"spacing": 0.01})") {
    return with_obstacle(R"({"mesh": ")" + mesh + R"(", "scale": 0.04, "translate": [0.25, 0.03, 0.02], "skin": )" +
                             skin + "}",
                         sph);
  };
  CHECK(test::scene_error(skinned(box, "{}")).empty());
  std::string e = test::scene_error(skinned(box, "{}", R"({"spacing": 0.01, "solver": "pbf"})"));
  CHECK((has(e, "obstacles.0.skin") && has(e, "pbf")));
  e = test::scene_error(skinned(box, R"({"resolution": 2})"));
  CHECK(has(e, "obstacles.0.skin.resolution"));
  e = test::scene_error(skinned(box, R"({"wave_speed": 0})"));
  CHECK(has(e, "obstacles.0.skin.wave_speed"));
  e = test::scene_error(skinned(box, R"({"frequency": -1})"));
  CHECK(has(e, "obstacles.0.skin.frequency"));
  e = test::scene_error(skinned(box, R"({"damping": -1})"));
  CHECK(has(e, "obstacles.0.skin.damping"));
  e = test::scene_error(skinned(box, R"({"compliance": -1e-6})"));
  CHECK(has(e, "obstacles.0.skin.compliance"));
  e = test::scene_error(skinned(box, R"({"stencil": "cubic"})"));
  CHECK(has(e, "obstacles.0.skin.stencil"));
  e = test::scene_error(skinned(box, R"({"speed": 1})"));
  CHECK(has(e, "obstacles.0.skin.speed"));
  e = test::scene_error(with_obstacle(R"({"mesh": ")" + torus +
                                     R"(", "scale": 0.03, "translate": [0.25, 0.05, 0.1], "skin": {}})"));
  CHECK((has(e, "obstacles.0.skin") && has(e, "torus") && has(e, "genus-0")));
}

namespace {

// The 6 cm cube of the buoyancy check with a skin, stiff and heavily damped
// so that it settles within a few hundredths of a second: where the pool's
// pressure p = rho g depth holds still, the skin dents by h = -C p (the
// foundation's balance; the wave term is small, s / w0 = 1.6 mm against
// the 6 cm faces). Per texel on the cube's faces away from its edges, the
// height and the load averaged over t = 0.1 .. 0.2 s against the analytic
// pressure at the texel's depth below the pool's surface.
struct DentError {
  double height = 0, load = 0;  // RMS relative errors
  size_t texels = 0;
};
DentError skin_dent(Backend backend, const std::string& solver) {
  const std::string text = R"({"tank": {"min": [0, 0, 0], "max": [0.2, 0.2, 0.2]},
    "fluid": [{"min": [0, 0, 0], "max": [0.2, 0.2, 0.16]}],
    "obstacles": [{"mesh": ")" + unit_box_obj() + R"(", "scale": 0.06, "translate": [0.07, 0.07, 0.05],
                   "skin": {"resolution": 16, "wave_speed": 0.1, "frequency": 10, "damping": 100,
                            "compliance": 1e-6}}],
    "sph": {"spacing": 0.01, "solver": ")" + solver + R"("}})";
  const Scene s = parse_scene(text, "t.json");
  const ResolvedScene r = resolve_scene(s);
  const SolverInput in = make_solver_input(r, PresenceMode::Off);
  auto solver_ptr = backend == Backend::Cuda ? make_cuda_solver(in) : make_cpu_solver(in);
  Solver& sv = *solver_ptr;
  REQUIRE(sv.skins() != nullptr);
  const SkinGeometry& g = sv.skins()->geometry(0);
  std::vector<double> h(g.map.size(), 0.0), load(g.map.size(), 0.0);
  int samples = 0;
  for (double t = 0.1; t <= 0.2 + 1e-9; t += 0.01) {
    test::run_until(sv, t);
    const std::vector<float> hk = sv.skins()->heights(0), lk = sv.skins()->loads(0);
    for (size_t i = 0; i < h.size(); ++i) {
      h[i] += hk[i];
      load[i] += lk[i];
    }
    ++samples;
  }
  // The pool's surface: the mean height of the top particles' layer.
  const HostParticles p = sv.download();
  double top = 0;
  for (const Vec3f& x : p.pos) top = std::max(top, double(x.z));
  top += 0.5 * s.sph.spacing;
  DentError e;
  double sh = 0, sl = 0;
  for (size_t i = 0; i < h.size(); ++i) {
    const Vec3d x = g.map.point[i];
    const double lo = 0.07 + 0.01, hi = 0.13 - 0.01;  // away from the cube's edges
    const bool inner = (x.x > lo && x.x < hi) + (x.y > lo && x.y < hi) + (x.z > 0.06 && x.z < 0.10) >= 2;
    if (!inner) continue;
    const double p_exact = 1000.0 * 9.81 * (top - x.z);
    const double dent = -1e-6 * p_exact;
    sh += std::pow((h[i] / samples - dent) / dent, 2);
    sl += std::pow((load[i] / samples - p_exact) / p_exact, 2);
    ++e.texels;
  }
  e.height = std::sqrt(sh / e.texels);
  e.load = std::sqrt(sl / e.texels);
  return e;
}

// DFSPH's pressure of one step is noisy (its solve stops at a tolerance;
// Solver::pressures): its load is checked only through the dent, which the
// damped skin averages over many steps.
void check_dent(Backend backend, const std::string& solver, double load_tol, double dent_tol) {
  const DentError e = skin_dent(backend, solver);
  INFO(solver << ": RMS relative error of the load " << e.load << ", of the dent " << e.height << " over " << e.texels
              << " texels");
  CHECK(e.texels > 200);
  if (load_tol > 0) CHECK(e.load < load_tol);
  CHECK(e.height < dent_tol);
}

}  // namespace

TEST_CASE("a skin under a still pool dents by its compliance times the hydrostatic pressure", "[mesh][cpu]") {
  check_dent(Backend::Cpu, "wcsph", 0.02, 0.02);
}

TEST_CASE("a skin under DFSPH dents by its compliance times the hydrostatic pressure", "[mesh][cpu]") {
  check_dent(Backend::Cpu, "dfsph", 0, 0.02);
}

TEST_CASE("cuda: a skin under a still pool dents by its compliance times the hydrostatic pressure", "[gpu]") {
  check_dent(Backend::Cuda, "wcsph", 0.02, 0.02);
  check_dent(Backend::Cuda, "dfsph", 0, 0.02);
}
