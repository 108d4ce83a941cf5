// The sphray executable end to end: exit codes and messages for bad input,
// a short run that succeeds.
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <set>
#include <string>
#include <sys/wait.h>

#include <nlohmann/json.hpp>

#include "catch.h"
#include "helpers.h"
#include "io/frames_h5.h"
#include "mesh/mesh.h"
#include "render/render.h"

// This process's own directory (helpers.h), and its name.
const std::string tmp = sphray::test::tmp_dir();
const std::string tmp_name = std::filesystem::path(tmp).filename().string();

namespace {

using Result = sphray::test::CliResult;
using sphray::test::has;
using sphray::test::run_cli;
using sphray::test::slurp;


}  // namespace

TEST_CASE("sphray run reports bad input with exit code 2", "[cli][cpu]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  Result r = run_cli("run /nonexistent.json --backend cpu");
  CHECK(r.code == 2);
  CHECK(has(r.output, "cannot open scene file"));
  {  // an output on the scene file, or two outputs on one path: refused, the scene left as it was
    std::filesystem::copy_file(scene, tmp + "/sphray_own.json", std::filesystem::copy_options::overwrite_existing);
    const std::string before = slurp(tmp + "/sphray_own.json");
    r = run_cli("run " + tmp + "/sphray_own.json --backend cpu --quiet --export " + tmp + "/../" + tmp_name + "/sphray_own.json");
    CHECK(r.code == 2);
    CHECK(has(r.output, "--export: '" + tmp + "/../" + tmp_name + "/sphray_own.json' is the scene file itself; not overwritten"));
    r = run_cli("run " + tmp + "/sphray_own.json --backend cpu --quiet --metrics-csv " + tmp + "/sphray_o.csv "
                "--summary-json " + tmp + "/sphray_o.csv");
    CHECK(r.code == 2);
    CHECK(has(r.output, "--summary-json: '" + tmp + "/sphray_o.csv' is also --metrics-csv"));
    CHECK(slurp(tmp + "/sphray_own.json") == before);
  }
  r = run_cli("rnu " + scene);  // CLI11 alone said "A subcommand is required"
  CHECK(r.code == 2);
  CHECK(has(r.output, "unknown command 'rnu': one of run, render, view, inspect, bench"));
  r = run_cli("bench simm");
  CHECK(r.code == 2);
  CHECK(has(r.output, "unknown command 'simm' after 'bench': one of sim, field, frame, render, surface, mesh, skin"));
  r = run_cli("bench sim --backend cpu --steps -3");  // CLI11's own check, with sphray's prefix
  CHECK(r.code == 2);
  CHECK(has(r.output, "sphray: error: --steps: Value -3 not in range"));  // CLI11 2.3 and 2.4 word the range differently
  r = run_cli("bench surface --backend cpu --cells 24 --layers 21");  // refused before the pool is built
  CHECK(r.code == 2);
  CHECK(has(r.output, "--layers 21 leaves less than 4 spacings of the 24-spacing tank above the pool (at most 20)"));
  r = run_cli("run " + sphray::test::source_path("scenes") + " --backend cpu");
  CHECK(r.code == 2);
  CHECK(has(r.output, "scenes: is a directory, not a scene file"));

  r = run_cli("run " + scene + " --backend cpu --set sph.spacing=-1");
  CHECK(r.code == 2);
  CHECK(has(r.output, "sph.spacing = -1"));

  r = run_cli("run " + scene + " --backend cpu --set sph.visc=0.1");
  CHECK(r.code == 2);
  CHECK(has(r.output, "unknown key"));

  r = run_cli("run " + scene + " --backend warp");
  CHECK(r.code == 2);
  CHECK(has(r.output, "auto, cpu or cuda"));

  r = run_cli("run " + scene + " --backend cpu --summary-json /nonexistent/dir/s.json");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--summary-json: cannot write"));
  CHECK_FALSE(has(r.output, "summary (cpu)"));  // refused before the run, not after

  r = run_cli("run " + scene + " --frobnicate");
  CHECK(r.code == 2);

  std::ofstream(tmp + "/sphray_bad.json") << "{\"tank\": [1,2";
  r = run_cli("run " + tmp + "/sphray_bad.json --backend cpu");
  CHECK(r.code == 2);
  CHECK(has(r.output, "not valid JSON"));
}

TEST_CASE("sphray run simulates a small scene and prints a summary", "[cli][cpu]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  const Result r = run_cli("run " + scene + " --backend auto --set run.end_time=0.05 --set run.output_interval=0.01 --metrics-csv " + tmp + "/sphray_m.csv");
  CHECK(r.code == 0);
  CHECK(has(r.output, "backend: "));
  CHECK(has(r.output, "summary"));
  CHECK(has(r.output, "8 fluid at start, 8 at end"));
  std::ifstream csv(tmp + "/sphray_m.csv");
  std::string header, line;
  std::getline(csv, header);
  CHECK(has(header, "front_m"));
  int rows = 0;
  while (std::getline(csv, line)) ++rows;
  CHECK(rows == 6);  // t = 0 and five output intervals of 0.01 s
}

TEST_CASE("sphray run warns when the wall guard, not the walls, held the liquid", "[cli][cpu]") {
  // One wall layer where the support needs four: 28% of the particle-steps of
  // this coarse dam break end on a wall face (0.03% with four). The summary
  // JSON's counts are checked against the bound independently of the text.
  const std::string run = "run " + sphray::test::source_path("scenes/dam_break.json") +
                          " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.3"
                          " --summary-json " + tmp + "/sphray_clamps.json";
  for (const bool thin : {true, false}) {
    INFO((thin ? "one layer" : "auto layers"));
    const Result r = run_cli(run + (thin ? " --set sph.boundary_layers=1" : ""));
    REQUIRE(r.code == 0);
    std::ifstream f(tmp + "/sphray_clamps.json");
    const nlohmann::json j = nlohmann::json::parse(f);
    CHECK(j.at("status") == "completed");
    const double share = j.at("clamped").get<double>() / j.at("particle_steps").get<double>();
    CHECK(j.at("particle_steps").get<double>() == j.at("steps").get<double>() * j.at("fluid_start").get<double>());
    CHECK((share > sphray::kWallClampShareBound) == thin);
    CHECK(has(r.output, "note: sph.boundary_layers = 1 is thinner than the kernel support (4 layers") == thin);
    CHECK(has(r.output, "warning        the wall guard, not the walls' pressure, held the liquid") == thin);
  }
}

TEST_CASE("the summary names the limit that held the steps", "[cli][cpu]") {
  // A block thrown at 1.5 m/s without gravity: WCSPH's steps are held by its
  // CFL (the speed of sound: about 1 ms at this spacing), or by run.max_dt
  // set below it, PBF's by its flow CFL (13 ms at 1.5 m/s) below a large
  // run.max_dt, and DFSPH's by its explicit viscosity's limit at a large
  // dfsph.viscosity (microseconds).
  std::ofstream(tmp + "/sphray_bounds.json") << R"({"tank": {"min": [0,0,0], "max": [0.4,0.2,0.2]},
    "fluid": [{"min": [0.1,0.06,0.06], "max": [0.18,0.14,0.14], "velocity": [1.5,0,0]}],
    "gravity": [0,0,0], "sph": {"spacing": 0.02}, "run": {"end_time": 0.02}})";
  struct Case {
    const char* solver;
    const char* set;
    const char* key;
    const char* name;
  };
  const Case cases[] = {
      {"wcsph", "", "cfl", "the CFL (sound and flow speed, sph.cfl)"},
      {"wcsph", " --set run.max_dt=1e-4", "max_dt", "run.max_dt"},
      {"pbf", " --set run.max_dt=1 --set run.end_time=0.1", "cfl", "the flow CFL (sph.cfl)"},
      {"dfsph", " --set dfsph.viscosity=10 --set run.end_time=0.001", "solver",
       "the explicit viscosity's limit (dfsph.viscosity)"}};
  for (const Case& c : cases) {
    INFO(c.solver << c.set);
    const std::string json = tmp + "/sphray_bounds_summary.json";
    const Result r = run_cli("run " + tmp + "/sphray_bounds.json --backend cpu --quiet --set sph.solver=" + c.solver +
                             c.set + " --summary-json " + json);
    INFO(r.output);
    REQUIRE(r.code == 0);
    const nlohmann::json j = nlohmann::json::parse(slurp(json));
    const nlohmann::json& b = j.at("step_bounds");
    uint64_t sum = 0;
    for (const char* k : {"cfl", "solver", "viscous", "max_dt"}) sum += b.at(k).get<uint64_t>();
    CHECK(sum == j.at("steps").get<uint64_t>());
    CHECK(b.at(c.key).get<uint64_t>() == sum);
    CHECK(has(r.output, std::string("step size      held by ") + c.name + " in 100% of the steps\n"));
    // A viscosity whose limit lies far below the flow's step is named before the run.
    const bool viscous = std::string(c.key) == "solver";
    CHECK(has(r.output, "note: dfsph.viscosity = 10 m^2/s limits the step to") == viscous);
    if (viscous) CHECK(j.at("mean_dt_s").get<double>() < 1e-4);
  }
}

TEST_CASE("the summary says where and when the largest speed was reached", "[cli][cpu]") {
  // Without gravity a small block thrown at 1.5 m/s beside a block at rest
  // holds the largest speed: the summary's particle lies in the thrown block
  // (moved by at most 1.5 m/s x t), at a time within the run, under every solver.
  std::ofstream(tmp + "/sphray_thrown.json") << R"({"tank": {"min": [0,0,0], "max": [0.4,0.2,0.2]},
    "fluid": [{"min": [0,0,0], "max": [0.1,0.2,0.1]},
              {"min": [0.22,0.08,0.08], "max": [0.26,0.12,0.12], "velocity": [1.5,0,0]}],
    "gravity": [0,0,0], "sph": {"spacing": 0.02}, "run": {"end_time": 0.02}})";
  for (const char* solver : {"wcsph", "pbf", "dfsph"}) {
    INFO(solver);
    const std::string json = tmp + "/sphray_thrown_" + solver + ".json";
    const Result r = run_cli("run " + tmp + "/sphray_thrown.json --backend cpu --quiet --set sph.solver=" + solver +
                             " --summary-json " + json);
    INFO(r.output);
    REQUIRE(r.code == 0);
    const nlohmann::json j = nlohmann::json::parse(slurp(json));
    CHECK(std::abs(j.at("max_speed_m_s").get<double>() - 1.5) < 0.15);
    const double t = j.at("max_speed_time_s").get<double>();
    CHECK(t >= 0.0);
    CHECK(t < 0.02);
    const auto at = j.at("max_speed_position_m").get<std::vector<double>>();
    REQUIRE(at.size() == 3);
    CHECK(at[0] >= 0.22);
    CHECK(at[0] <= 0.26 + 1.5 * t + 1e-6);
    CHECK(at[1] >= 0.08);
    CHECK(at[1] <= 0.12);
    CHECK(at[2] >= 0.08);
    CHECK(at[2] <= 0.12);
    // Initial indices follow the blocks: the first holds 5 x 10 x 5.
    CHECK(j.at("max_speed_particle").get<uint32_t>() >= 250u);
    CHECK(has(r.output, "max speed"));
  }
}

TEST_CASE("a run stopped by a guard exits 1 and leaves a summary JSON that says so", "[cli][cpu]") {
  // The particle dropped 0.3 m with c0 = 2 m/s outruns c0 at t = 0.204 s
  // (free fall, tests/test_sph.cpp); the summary file, opened before the run,
  // was left empty.
  std::ofstream(tmp + "/sphray_drop.json") << R"({"tank": {"min": [0,0,0], "max": [0.1,0.1,0.4]},
    "fluid": [{"min": [0.045,0.045,0.295], "max": [0.055,0.055,0.305]}],
    "sph": {"spacing": 0.01, "speed_of_sound": 2}, "run": {"end_time": 0.4}})";
  const Result r =
      run_cli("run " + tmp + "/sphray_drop.json --backend cpu --quiet --summary-json " + tmp + "/sphray_drop_summary.json");
  CHECK(r.code == 1);
  CHECK(has(r.output, "faster than the speed of sound"));
  std::ifstream f(tmp + "/sphray_drop_summary.json");
  const nlohmann::json j = nlohmann::json::parse(f);
  CHECK(j.at("status") == "stopped");
  CHECK(has(j.at("error").get<std::string>(), "faster than the speed of sound c0 = 2 m/s"));
  CHECK(j.at("steps").get<int>() > 0);
  CHECK(j.at("sim_time_s").get<double>() == Approx(0.204).margin(0.002));
}

TEST_CASE("sphray run builds the field at every frame when the scene has one", "[cli][cpu]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  const Result r = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.02 --set run.output_interval=0.01 "
                           "--set field.builder=presence --summary-json " + tmp + "/sphray_field_summary.json");
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK(has(r.output, "field          presence builder"));
  CHECK(has(r.output, "3 builds"));               // t = 0 and two frames
  CHECK(has(r.output, "1 without presence"));     // only t = 0: the frames' last steps computed it
  CHECK(has(slurp(tmp + "/sphray_field_summary.json"), "\"builds_without_presence\": 1"));
  CHECK(has(r.output, "isotropic kernels"));
  // With ellipsoids the summary says so.
  const Result a = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.02 --set run.output_interval=0.01 "
                           "--set field.kernel=anisotropic --summary-json " + tmp + "/sphray_field_summary_aniso.json");
  INFO(a.output);
  CHECK(a.code == 0);
  CHECK(has(a.output, "presence builder, anisotropic kernels"));
  CHECK(has(slurp(tmp + "/sphray_field_summary_aniso.json"), "\"kernel\": \"anisotropic\""));
  // Zhu & Bridson's surface: the gather builder, named so.
  const Result z = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.02 --set run.output_interval=0.01 "
                           "--set field.kernel=zhu_bridson --summary-json " + tmp + "/sphray_field_summary_zb.json");
  INFO(z.output);
  CHECK(z.code == 0);
  CHECK(has(z.output, "gather builder, zhu_bridson surface"));
  CHECK(has(z.output, "3 builds"));
  CHECK(has(slurp(tmp + "/sphray_field_summary_zb.json"), "\"builds_without_presence\": 0"));  // it reads none
  CHECK(has(slurp(tmp + "/sphray_field_summary_zb.json"), "\"kernel\": \"zhu_bridson\""));
}

TEST_CASE("sphray bench sim writes every row with its stages and its wall time", "[cli][cpu]") {
  const std::string json_path = tmp + "/sphray_cli_bench_sim.json";
  std::remove(json_path.c_str());
  const std::string scene = sphray::test::source_path("scenes/bench/dam_break.json");
  const Result r =
      run_cli("bench sim --backend cpu --scene " + scene + " --sizes 2k --warmup 1 --steps 3 --json " + json_path);
  REQUIRE(r.code == 0);
  std::ifstream f(json_path);
  REQUIRE(f.good());
  const nlohmann::json j = nlohmann::json::parse(f);
  REQUIRE(j["rows"].size() == 2);  // presence off and on
  for (const auto& row : j["rows"]) {
    const double grid = row["grid_ms"], pairs = row["pairs_ms"], integrate = row["integrate_ms"];
    const double total = row["total_ms"], wall = row["wall_ms"];
    CHECK(grid > 0);
    CHECK(pairs > 0);
    CHECK(integrate > 0);
    // The stages are timed inside each step, so each step's wall time (the
    // host's clock around the whole call) is at least their sum, and so are
    // the medians.
    CHECK(wall >= total);
    // Simulated seconds per wall second at the step the solver chose.
    const double dt = row["dt_s"];
    CHECK(dt > 0);
    CHECK(double(row["steps_per_simulated_s"]) == Approx(1.0 / dt));
    CHECK(double(row["realtime_factor"]) == Approx(dt / (1e-3 * wall)));
  }
  // Without --scene, the built-in copy of the same scene, from any directory
  // (the default was a path relative to the repository's root).
  const std::string builtin_json = tmp + "/sphray_cli_bench_builtin.json";
  std::remove(builtin_json.c_str());
  CHECK(std::system(("cd / && " + std::string(SPHRAY_EXE) + " bench sim --backend cpu --sizes 2k --warmup 1 --steps 1 "
                     "--json " + builtin_json + " > /dev/null 2>&1").c_str()) == 0);
  const nlohmann::json b = nlohmann::json::parse(slurp(builtin_json));
  REQUIRE(b["rows"].size() == 2);
  CHECK(b["rows"][0]["particles"] == j["rows"][0]["particles"]);
  CHECK(b["rows"][0]["boundary_particles"] == j["rows"][0]["boundary_particles"]);
  // An unwritable --json fails before the benchmark runs, not after it.
  const Result bad = run_cli("bench sim --backend cpu --scene " + scene + " --sizes 2k --json /nonexistent/dir/b.json");
  CHECK(bad.code == 2);
  CHECK(has(bad.output, "--json: cannot write '/nonexistent/dir/b.json': No such file or directory"));
  CHECK_FALSE(has(bad.output, "presence"));  // no table row printed
}

TEST_CASE("sphray bench sim --solvers runs each solver in turn, and refuses an unknown one", "[cli][cpu]") {
  const std::string json_path = tmp + "/sphray_cli_bench_solvers.json";
  std::remove(json_path.c_str());
  const Result r = run_cli("bench sim --backend cpu --sizes 1k --warmup 0 --steps 2 --solvers pbf,dfsph,wcsph --json " +
                           json_path);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(slurp(json_path));
  REQUIRE(j["rows"].size() == 6);  // three solvers, presence off and on
  const char* want[] = {"pbf", "pbf", "dfsph", "dfsph", "wcsph", "wcsph"};
  for (size_t k = 0; k < 6; ++k) CHECK(j["rows"][k]["solver"] == want[k]);
  CHECK(int(j["rows"][2]["iterations"]) >= 2);              // DFSPH's pressure solve: at least its minimum
  CHECK(int(j["rows"][2]["divergence_iterations"]) >= 1);
  CHECK(int(j["rows"][4]["iterations"]) == 0);              // WCSPH has no solve
  const Result bad = run_cli("bench sim --backend cpu --sizes 1k --solvers pbf,isph");
  // PBF has no pressure to export.
  const std::string scene = sphray::test::source_path("scenes/dam_break.json");
  const Result no_pressure = run_cli("run " + scene + " --backend cpu --set sph.solver=pbf --set run.end_time=0.01 --export " +
                                     tmp + "/sphray_pbf_pressure.h5 --export-fields pressure");
  CHECK(no_pressure.code == 2);
  CHECK(has(no_pressure.output, "the pbf solver has no pressure"));
  CHECK(bad.code == 2);
  CHECK(has(bad.output, "\"wcsph\", \"pbf\", \"dfsph\""));
}

TEST_CASE("sphray bench field reports bad input with exit code 2", "[cli][cpu]") {
  Result r = run_cli("bench field --backend cpu --sizes 8k --json /nonexistent/dir/out.json");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--json: cannot write"));
  r = run_cli("bench field --backend cpu --sizes lots");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--sizes"));
  r = run_cli("bench field --backend cpu --sizes 8k --set field.refine=7");
  CHECK(r.code == 2);
  CHECK(has(r.output, "field.refine"));
}

TEST_CASE("sphray run --export and sphray inspect: bad paths and bad files exit 2 with a message", "[cli][export]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  Result r = run_cli("run " + scene + " --backend cpu --quiet --export /nonexistent/dir/out.h5");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--export: /nonexistent/dir/out.h5: cannot create the export file"));
  // One line: HDF5's own description of the failed open carries a timestamp
  // with a line break in it ("unable to open file: time = ..."), cut off.
  CHECK(!has(r.output, "time = "));
  CHECK(r.output.find('\n', r.output.find("cannot create the export file")) + 1 == r.output.size());
  // The XDMF sidecar (NAME.xmf) renamed over an export named NAME.xmf left only the XML.
  std::filesystem::remove(tmp + "/sphray_side.xmf");
  r = run_cli("run " + scene + " --backend cpu --quiet --export " + tmp + "/sphray_side.xmf");
  CHECK(r.code == 2);
  CHECK(has(r.output, tmp + "/sphray_side.xmf: that is the name of the XDMF sidecar written next to the export"));
  CHECK_FALSE(std::filesystem::exists(tmp + "/sphray_side.xmf"));
  std::filesystem::copy_file(scene, tmp + "/sphray_scene.xmf", std::filesystem::copy_options::overwrite_existing);
  r = run_cli("run " + tmp + "/sphray_scene.xmf --backend cpu --quiet --export " + tmp + "/sphray_scene.h5");
  CHECK(r.code == 2);
  CHECK(has(r.output, "the export's XDMF sidecar: '" + tmp + "/sphray_scene.xmf' is the scene file itself"));
  r = run_cli("run " + scene + " --backend cpu --quiet --export " + tmp + "/x.h5 --export-fields velocity,colour");
  CHECK(r.code == 2);
  CHECK(has(r.output, "unknown field 'colour'"));
  r = run_cli("inspect /nonexistent.h5");
  CHECK(r.code == 2);
  CHECK(has(r.output, "missing or unreadable"));
  std::ofstream(tmp + "/sphray_cli_text.h5") << "plain text";
  r = run_cli("inspect " + tmp + "/sphray_cli_text.h5");
  CHECK(r.code == 2);
  CHECK(has(r.output, "not an HDF5 file"));

  r = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.02 --set run.output_interval=0.01 "
              "--export " + tmp + "/sphray_cli.h5 --export-every 2 --export-fields density");
  CHECK(r.code == 0);
  CHECK(has(r.output, "2 frames to " + tmp + "/sphray_cli.h5"));  // t = 0 and t = 0.02
  r = run_cli("inspect " + tmp + "/sphray_cli.h5");
  CHECK(r.code == 0);
  CHECK(has(r.output, "frames 2"));
  CHECK(has(r.output, "000001  t = 0.02 s"));
  CHECK(has(r.output, "density ["));
  {  // non-finite values other than positions: counted beside the ranges (min/max alone skipped them)
    sphray::FrameWriter w(tmp + "/sphray_cli_nan.h5", sphray::FileHeader{"{}", "test", "cpu", {}}, 0);
    sphray::Frame f;
    f.id = {0, 1, 2};
    f.position.assign(9, 0.5f);
    f.density = {1000.0f, NAN, 1002.0f};
    f.velocity = {0, 0, 1, INFINITY, 0, 0, 0, 2, 0};
    w.submit(std::move(f));
    w.finish();
  }
  r = run_cli("inspect " + tmp + "/sphray_cli_nan.h5");
  CHECK(r.code == 0);
  CHECK(has(r.output, "density [1000, 1002] (1 non-finite)"));
  CHECK(has(r.output, "|v| max 2 (1 non-finite)"));
  // an export where a scene goes: told what it is and what to run instead
  r = run_cli("run " + tmp + "/sphray_cli.h5 --backend cpu");
  CHECK(r.code == 2);
  CHECK(has(r.output, tmp + "/sphray_cli.h5: is an HDF5 file, not a scene"));
  CHECK(has(r.output, "sphray render --from " + tmp + "/sphray_cli.h5"));
}

TEST_CASE("sphray run --resume refuses an export of another spacing or other fluid blocks, naming what differs",
          "[cli][cpu]") {
  // A frame's ids index the lattice of the scene that wrote it: at a finer
  // spacing every id exists but names another particle, with another mass;
  // at other blocks they are other particles too.
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  const std::string from = tmp + "/sphray_cli_resume.h5";
  for (const char* solver : {"wcsph", "pbf"}) {
    INFO(solver);
    const std::string base = "run " + scene + " --backend cpu --quiet --set sph.solver=" + solver;
    Result r = run_cli(base + " --set run.end_time=0.02 --export " + from + " --export-fields velocity,density");
    REQUIRE(r.code == 0);
    r = run_cli(base + " --set run.end_time=0.04 --resume " + from);
    CHECK(r.code == 0);
    r = run_cli(base + " --set run.end_time=0.04 --set sph.spacing=0.005 --resume " + from);
    CHECK(r.code == 2);
    CHECK(has(r.output, "--resume: " + from + " was exported from another scene or spacing: its sph.spacing is 0.01, "
                        "this scene's 0.005"));
    r = run_cli(base + " --set run.end_time=0.04 --set fluid.0.max=[0.07,0.06,0.06] --resume " + from);
    CHECK(r.code == 2);
    CHECK(has(r.output, "its fluid blocks (min, max) are not this scene's"));
    // The blocks' velocity is not the lattice: the frame's velocities replace it.
    r = run_cli(base + " --set run.end_time=0.04 --set fluid.0.velocity=[1,0,0] --resume " + from);
    CHECK(r.code == 0);
  }
}

TEST_CASE("sphray run --frames-dir and sphray render write PNGs of the liquid; render --from an export matches",
          "[cli][render]") {
  const std::string scene = sphray::test::source_path("scenes/dam_break.json");
  const std::string small = " --backend cpu --set sph.spacing=0.04 --set field.builder=naive --size 96x54 ";
  std::system(("rm -rf " + tmp + "/sphray_frames " + tmp + "/sphray_render_*.png " + tmp + "/sphray_render.h5 " + tmp +
               "/sphray_render.xmf").c_str());
  Result r = run_cli("run " + scene + small + "--quiet --set run.end_time=0.04 --set run.output_interval=0.01 "
                     "--frames-dir " + tmp + "/sphray_frames --frames-every 2 --export " + tmp + "/sphray_render.h5");
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(has(r.output, "3 PNGs (96x54, 4 interfaces) to " + tmp + "/sphray_frames"));
  for (const char* f : {"frame_000000.png", "frame_000002.png", "frame_000004.png"}) {
    const sphray::Image img = sphray::read_png(std::string(tmp + "/sphray_frames/") + f);
    CHECK(img.width == 96);
    CHECK(img.height == 54);
  }
  CHECK_FALSE(std::ifstream(tmp + "/sphray_frames/frame_000001.png").good());

  // the liquid is in the picture: the same tank without fluid renders differently
  r = run_cli("render " + scene + small + "--set fluid=[] --time 0 --out " + tmp + "/sphray_render_empty.png");
  REQUIRE(r.code == 0);
  const sphray::Image empty = sphray::read_png(tmp + "/sphray_render_empty.png");
  const sphray::Image t0 = sphray::read_png(tmp + "/sphray_frames/frame_000000.png");
  CHECK(sphray::pixels_differing(t0, empty, 20) > t0.rgba.size() / 50);  // the column covers more than 2% of the image

  // the exported particles render as the run rendered them (field rebuilt from the file's positions)
  r = run_cli("render --from " + tmp + "/sphray_render.h5 --frame 4 --out " + tmp + "/sphray_render_from.png" + small);
  INFO(r.output);
  REQUIRE(r.code == 0);
  const sphray::Image from = sphray::read_png(tmp + "/sphray_render_from.png");
  const sphray::Image live = sphray::read_png(tmp + "/sphray_frames/frame_000004.png");
  CHECK(sphray::psnr(from, live) > 40.0);
  // the export given where the scene goes renders as with --from
  r = run_cli("render " + tmp + "/sphray_render.h5 --frame 4 --out " + tmp + "/sphray_render_positional.png" + small);
  REQUIRE(r.code == 0);
  CHECK(sphray::pixels_differing(sphray::read_png(tmp + "/sphray_render_positional.png"), from, 0) == 0);
  r = run_cli("render --from " + tmp + "/sphray_render.h5 --out " + tmp + "/sphray_render_dir" + small);
  CHECK(r.code == 0);
  CHECK(has(r.output, "rendered 5 frames"));
}

TEST_CASE("each render method writes frames; screen_space builds no field", "[cli][render]") {
  const std::string scene = sphray::test::source_path("scenes/dam_break.json");
  const std::string small = " --backend cpu --set sph.spacing=0.04 --size 96x54 --quiet --set run.end_time=0.02 "
                            "--set run.output_interval=0.01 ";
  const std::string raycast = tmp + "/sphray_method_raycast";
  std::system(("rm -rf " + tmp + "/sphray_method_*").c_str());
  Result r = run_cli("run " + scene + small + "--frames-dir " + raycast);
  REQUIRE(r.code == 0);
  CHECK(has(r.output, "3 builds"));
  for (const char* m : {"screen_space", "slices"}) {
    const std::string dir = tmp + "/sphray_method_" + m;
    r = run_cli("run " + scene + small + "--frames-dir " + dir + " --set render.method=\"" + m + "\"");
    INFO(m << ": " << r.output);
    REQUIRE(r.code == 0);
    CHECK(has(r.output, "3 PNGs (96x54"));
    CHECK(has(r.output, "3 builds") == (std::string(m) == "slices"));  // screen_space draws the particles
    // the same liquid in the picture as the raycaster's
    const sphray::Image a = sphray::read_png(raycast + "/frame_000002.png");
    const sphray::Image b = sphray::read_png(dir + "/frame_000002.png");
    CHECK(sphray::psnr(a, b) > 20.0);
  }
  const std::string one = " --backend cpu --set sph.spacing=0.04 --size 96x54 --time 0 --out " + tmp;
  r = run_cli("render " + scene + one + "/sphray_method_one.png --set render.method=\"screen_space\"");
  CHECK(r.code == 0);
  CHECK(std::ifstream(tmp + "/sphray_method_one.png").good());
  r = run_cli("render " + scene + one + "/sphray_method_bad.png --set render.method=\"phong\"");
  CHECK(r.code == 2);
  CHECK(has(r.output, "render.method"));
  CHECK(has(r.output, "\"raycast\", \"screen_space\", \"slices\""));
}

TEST_CASE("sphray render and --frames-dir report bad input with exit code 2", "[cli][render]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  Result r = run_cli("run " + scene + " --backend cpu --frames-dir " + tmp + "/sphray_f --size 100by50");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--size '100by50'"));
  r = run_cli("run " + scene + " --backend cpu --size 100x50");
  CHECK(r.code == 2);
  CHECK(has(r.output, "need --frames-dir"));
  r = run_cli("run " + scene + " --backend cpu --frames-dir " + tmp + "/sphray_f --size 8x8");
  CHECK(r.code == 2);
  CHECK(has(r.output, "render.width"));
  r = run_cli("run " + scene + " --backend cpu --frames-dir /proc/sphray_frames");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--frames-dir: cannot"));
  CHECK_FALSE(has(r.output, "summary (cpu)"));
  r = run_cli("render " + scene + " --backend cpu --out /nonexistent/dir/x.png");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--out: cannot write '/nonexistent/dir/x.png': No such file or directory"));
  std::filesystem::create_directories(tmp + "/sphray_dir.png");  // a directory by a PNG's name: says so
  r = run_cli("render " + scene + " --backend cpu --out " + tmp + "/sphray_dir.png");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--out: cannot write '" + tmp + "/sphray_dir.png': Is a directory"));
  r = run_cli("render --backend cpu --out " + tmp + "/x.png");
  CHECK(r.code == 2);
  CHECK(has(r.output, "either a scene file or --from"));
  r = run_cli("render --from /nonexistent.h5 --backend cpu --out " + tmp + "/x.png");
  CHECK(r.code == 2);
  CHECK(has(r.output, "missing or unreadable"));
  // An image name of another format: refused before the run (it became a directory of PNGs).
  std::filesystem::remove_all(tmp + "/sphray_x.jpg");
  r = run_cli("render " + scene + " --backend cpu --out " + tmp + "/sphray_x.jpg");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--out '" + tmp + "/sphray_x.jpg': sphray writes PNG images"));
  CHECK_FALSE(std::filesystem::exists(tmp + "/sphray_x.jpg"));
  r = run_cli("view --frames 2 --screenshot " + tmp + "/sphray_x.JPEG");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--screenshot '" + tmp + "/sphray_x.JPEG': sphray writes PNG images; give a .png name"));
  r = run_cli("render " + scene + " --backend cpu --out /proc/sphray_frames");  // named as render's option
  CHECK(r.code == 2);
  CHECK(has(r.output, "--out: cannot create directory '/proc/sphray_frames'"));
  r = run_cli("render " + scene + " --backend cpu --out " + tmp + "/x.png --set render.interfaces=12");
  CHECK(r.code == 2);
  CHECK(has(r.output, "render.interfaces"));

  r = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.01 --set run.output_interval=0.01 "
              "--export " + tmp + "/sphray_render2.h5");
  REQUIRE(r.code == 0);
  r = run_cli("render --from " + tmp + "/sphray_render2.h5 --backend cpu --frame 5 --out " + tmp + "/x.png");
  CHECK(r.code == 2);
  CHECK(has(r.output, "holds frames 0 .. 1"));
  r = run_cli("render --from " + tmp + "/sphray_render2.h5 --backend cpu --out " + tmp + "/sphray_render2.h5");
  CHECK(r.code == 2);
  CHECK(has(r.output, "--out: '" + tmp + "/sphray_render2.h5' is the --from file itself; not overwritten"));
  r = run_cli("render --from " + tmp + "/sphray_render2.h5 --backend cpu --out " + tmp + "/x.png");
  CHECK(r.code == 2);
  CHECK(has(r.output, "give --frame K, or a directory"));
  r = run_cli("bench frame --backend cpu --sizes 8k --builder magic");
  CHECK(r.code == 2);
  CHECK(has(r.output, "magic"));
}

TEST_CASE("bench frame --realtime advances each frame by the previous frame's wall time, at most 1/30 s", "[cli][cpu]") {
  const std::string json = tmp + "/sphray_frame_realtime.json";
  const Result r = run_cli("bench frame --backend cpu --sizes 2k --width 96 --height 54 --warmup 1 --frames 3 --realtime "
                           "--collapse 0.5 --json " + json);
  INFO(r.output);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  REQUIRE(j["rows"].size() == 1);
  const auto& row = j["rows"][0];
  CHECK(row["realtime"] == true);
  CHECK(double(row["steps_per_frame"]) >= 1);
  // A frame's steps stop once they have taken about 1/30 s of wall time (the
  // budget, plus the step that spends it): on the CPU that is short of the
  // frame's target, so the run plays slower than real time at a steady rate.
  const double x = row["realtime_factor"], sim_ms = row["sim_ms"], steps = row["steps_per_frame"];
  CHECK(x > 0);
  CHECK(x < 1.0);
  CHECK(sim_ms <= 1000.0 / 30.0 + 2.0 * sim_ms / steps + 5.0);
}

TEST_CASE("bench mesh times the BVH and the collision pass and stops the paths that enter the mesh", "[cli][cpu]") {
  const std::string json = tmp + "/sphray_bench_mesh.json";
  const Result r = run_cli("bench mesh --backend cpu --levels 1,3 --particles 2000 --warmup 0 --frames 2 --json " + json);
  INFO(r.output);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  REQUIRE(j["rows"].size() == 2);
  CHECK(j["rows"][0]["triangles"] == 80);
  CHECK(j["rows"][1]["triangles"] == 1280);
  for (const auto& row : j["rows"]) {
    CHECK(double(row["build_ms"]) > 0);
    CHECK(double(row["stopped_near_share"]) > 0.0);  // paths near the ball, biased inward: some enter it
    CHECK(double(row["stopped_near_share"]) < 0.9);
  }
  CHECK(run_cli("bench mesh --backend cpu --levels 12").code == 2);
}

TEST_CASE("bench skin measures the waves' speed by direction for every stencil", "[cli][cpu]") {
  const std::string json = tmp + "/sphray_bench_skin.json";
  const Result r = run_cli("bench skin --backend cpu --resolutions 16 --warmup 0 --frames 1 --json " + json);
  INFO(r.output);
  REQUIRE(r.code == 0);
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  REQUIRE(j["rows"].size() == 3);
  for (const auto& row : j["rows"]) {
    CHECK(row["texels"] == 6 * 16 * 16);
    CHECK(double(row["speed_mean"]) == Approx(1.0).epsilon(0.1));
    CHECK(double(row["speed_min"]) <= double(row["speed_max"]));
  }
  CHECK(run_cli("bench skin --backend cpu --resolutions 4").code == 2);
}

TEST_CASE("a run with a skinned obstacle names its skin and the skins' cost", "[cli][cpu]") {
  const Result r = run_cli("run " + sphray::test::source_path("scenes/dam_break_bunny.json") +
                           " --backend cpu --set sph.spacing=0.04 --set run.end_time=0.02 --set obstacles.0.skin.resolution=16");
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(has(r.output, "a skin of 1536 texels"));
  CHECK(has(r.output, "mapped to the sphere after"));  // the bunny is not star-shaped
  CHECK(has(r.output, "obstacle skins"));
  const Result pbf = run_cli("run " + sphray::test::source_path("scenes/dam_break_bunny.json") + " --set sph.solver=pbf");
  CHECK(pbf.code == 2);
  CHECK(has(pbf.output, "obstacles.0.skin"));
  // DFSPH fills the bunny's skin with wall particles too, and says so.
  const Result df = run_cli("run " + sphray::test::source_path("scenes/dam_break_bunny.json") +
                            " --backend cpu --set sph.solver=dfsph --set sph.spacing=0.04 --set run.end_time=0.02"
                            " --set obstacles.0.skin.resolution=16");
  INFO(df.output);
  CHECK(df.code == 0);
  CHECK(has(df.output, "walls: the tank's planes and the obstacles' wall particles"));
  CHECK_FALSE(has(df.output, " 0 wall particles"));
}

TEST_CASE("an export carries the skins' heights and render --from draws them", "[cli][cpu]") {
  // A 6 cm cube with a skin in a still pool: dented by about C rho g depth (1e-6 m/Pa, 5-11 cm deep).
  const std::string box = tmp + "/skin_box.obj", scene = tmp + "/skin_pool.json", h5 = tmp + "/skin_pool.h5";
  sphray::write_obj(sphray::box_mesh({{0, 0, 0}, {1, 1, 1}}), box);
  std::ofstream(scene) << R"({"tank": {"min": [0, 0, 0], "max": [0.2, 0.2, 0.2]},
    "fluid": [{"min": [0, 0, 0], "max": [0.2, 0.2, 0.16]}],
    "obstacles": [{"mesh": ")" + box + R"(", "scale": 0.06, "translate": [0.07, 0.07, 0.05],
                   "skin": {"resolution": 8, "wave_speed": 0.1, "frequency": 10, "damping": 100}}],
    "sph": {"spacing": 0.02}, "run": {"end_time": 0.06, "output_interval": 0.03}})";
  const Result r = run_cli("run " + scene + " --backend cpu --export " + h5);
  INFO(r.output);
  REQUIRE(r.code == 0);
  const sphray::FrameReader reader(h5);
  REQUIRE(reader.frames().size() == 3);
  const sphray::Frame f = reader.read(2);
  REQUIRE(f.skins.size() == 1);
  CHECK(f.skins[0].obstacle == 0);
  CHECK(f.skins[0].n == 8);
  REQUIRE(f.skins[0].height.size() == 6 * 8 * 8);
  float lo = 0, hi = 0;
  for (const float h : f.skins[0].height) {
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  CHECK(lo < -5e-4f);  // the bottom face, 11 cm deep: about -1.1 mm
  CHECK(lo > -2e-3f);
  CHECK(hi < 1e-4f);
  const Result png = run_cli("render --from " + h5 + " --frame 2 --backend cpu --size 64x36 --out " + tmp + "/skin.png");
  INFO(png.output);
  CHECK(png.code == 0);
  CHECK(std::filesystem::exists(tmp + "/skin.png"));
}

TEST_CASE("sphray view draws a scene's obstacles", "[viewer]") {
  if (!SPHRAY_TEST_VIEWER || std::system("command -v xvfb-run > /dev/null 2>&1") != 0) {
    WARN("no viewer in this build, or no xvfb-run: not tested");
    return;
  }
  const std::string cmd = "xvfb-run -a -s '-screen 0 1024x768x24' " + std::string(SPHRAY_EXE) + " view " +
                          sphray::test::source_path("scenes/dam_break_obstacles.json") +
                          " --backend cpu --frames 2 --substeps 1 --size 480x270 --set sph.spacing=0.04 --screenshot ";
  REQUIRE(std::system((cmd + tmp + "/sphray_view_obst.png > /dev/null 2>&1").c_str()) == 0);
  REQUIRE(std::system((cmd + tmp + "/sphray_view_noobst.png --set 'obstacles=[]' > /dev/null 2>&1").c_str()) == 0);
  const sphray::Image a = sphray::read_png(tmp + "/sphray_view_obst.png"),
                      b = sphray::read_png(tmp + "/sphray_view_noobst.png");
  REQUIRE(a.rgba.size() == b.rgba.size());
  // The pier and the ball cover about 1.5% of the window (1,875 of 129,600
  // pixels when written); the liquid has barely moved, so without them the
  // two images would agree.
  const size_t differ = sphray::pixels_differing(a, b, 20);
  INFO(differ << " of " << a.rgba.size() << " pixels differ");
  CHECK(differ > a.rgba.size() / 200);
}

TEST_CASE("sphray view opens a real window under Xvfb and shows the liquid", "[viewer]") {
  if (!SPHRAY_TEST_VIEWER) {
    WARN("this sphray was built without the viewer (GLFW/GLEW/Dear ImGui not found): not tested");
    return;
  }
  if (std::system("command -v xvfb-run > /dev/null 2>&1") != 0) {
    WARN("xvfb-run is not installed (tools/setup.sh installs it): the viewer is not tested");
    return;
  }
  const std::string xvfb = "xvfb-run -a -s '-screen 0 1024x768x24' ";
  std::filesystem::remove(tmp + "/sphray_view.png");
  std::filesystem::remove(tmp + "/sphray_view_empty.png");
  const std::string cmd = xvfb + SPHRAY_EXE + " view --backend cpu --frames 4 --substeps 2 --size 800x450 --screenshot ";
  Result r{std::system((cmd + tmp + "/sphray_view.png > " + tmp + "/sphray_view.log 2>&1").c_str()), ""};
  std::ifstream lf(tmp + "/sphray_view.log");
  std::stringstream ls;
  ls << lf.rdbuf();
  INFO(ls.str());
  REQUIRE(r.code == 0);
  CHECK(has(ls.str(), "wrote " + tmp + "/sphray_view.png after 4 frames"));
  REQUIRE(std::system((cmd + tmp + "/sphray_view_empty.png --set fluid=[] > /dev/null 2>&1").c_str()) == 0);
  const sphray::Image a = sphray::read_png(tmp + "/sphray_view.png"), b = sphray::read_png(tmp + "/sphray_view_empty.png");
  REQUIRE(a.width == 800);
  REQUIRE(a.height == 450);
  REQUIRE(b.rgba.size() == a.rgba.size());
  // the window shows the raycast liquid: it differs from the same window over an empty tank
  const size_t differ = sphray::pixels_differing(a, b, 20);
  INFO(differ << " of " << a.rgba.size() << " pixels differ");
  CHECK(differ > a.rgba.size() / 50);
  // and it is not blank: many distinct colours
  std::set<uint32_t> colours(a.rgba.begin(), a.rgba.end());
  CHECK(colours.size() > 200);

  // Resized after the first frame, the image follows the window (no stretched
  // fixed-size image): the screenshot has the new size and shows the scene.
  std::filesystem::remove(tmp + "/sphray_view_resized.png");
  REQUIRE(std::system((xvfb + SPHRAY_EXE + " view --backend cpu --frames 8 --substeps 2 --size 800x450 --resize 480x400 "
                              "--screenshot " + tmp + "/sphray_view_resized.png > /dev/null 2>&1").c_str()) == 0);
  const sphray::Image c = sphray::read_png(tmp + "/sphray_view_resized.png");
  CHECK(c.width == 480);
  CHECK(c.height == 400);
  std::set<uint32_t> colours_c(c.rgba.begin(), c.rgba.end());
  CHECK(colours_c.size() > 200);
  // and it is the image a window opened at that size shows (a stretched 800x450 image would not be)
  REQUIRE(std::system((xvfb + SPHRAY_EXE + " view --backend cpu --frames 8 --substeps 2 --size 480x400 "
                              "--screenshot " + tmp + "/sphray_view_direct.png > /dev/null 2>&1").c_str()) == 0);
  const sphray::Image d = sphray::read_png(tmp + "/sphray_view_direct.png");
  REQUIRE(d.rgba.size() == c.rgba.size());
  const size_t resized_differ = sphray::pixels_differing(c, d, 20);
  INFO(resized_differ << " of " << c.rgba.size() << " pixels differ between the resized and the direct window");
  CHECK(resized_differ < c.rgba.size() / 100);

  // The default: real-time playback, each frame advancing the simulation by
  // the wall time of the one before (at most 1/30 s): after 6 frames the
  // simulated time is positive and no more than 5 such frames.
  const std::string rt_log = tmp + "/sphray_view_realtime.log";
  REQUIRE(std::system((xvfb + SPHRAY_EXE + " view --backend cpu --frames 6 --size 320x180 > " + rt_log + " 2>&1").c_str()) ==
          0);
  const std::string rt = slurp(rt_log);
  INFO(rt);
  const size_t at = rt.find("real-time playback, x");
  REQUIRE(at != std::string::npos);
  double factor = 0, t_end = -1;
  REQUIRE(std::sscanf(rt.c_str() + at, "real-time playback, x%lf real time", &factor) == 1);
  CHECK(factor > 0);
  const size_t t_at = rt.find(", t = ", at);
  REQUIRE(t_at != std::string::npos);
  REQUIRE(std::sscanf(rt.c_str() + t_at, ", t = %lf s", &t_end) == 1);
  CHECK(t_end > 0);
  CHECK(t_end <= 5.0 / 30.0 * (1 + 1e-5));  // the first frame has no previous one; t printed to 6 digits
  // The built-in scene runs PBF; under WCSPH the same playback is slow motion
  // (x0.11 on two cores), and the viewer says which solver steps faster.
  CHECK(!has(rt, "slow motion"));
  REQUIRE(std::system((xvfb + SPHRAY_EXE + " view --backend cpu --frames 6 --size 320x180 --set sph.solver=wcsph > " +
                       rt_log + " 2>&1").c_str()) == 0);
  const std::string rt_wcsph = slurp(rt_log);
  INFO(rt_wcsph);
  CHECK(has(rt_wcsph, "viewer: slow motion: WCSPH steps at the speed of sound; --set sph.solver=pbf"));

  Result bad = run_cli("view --backend cpu --screenshot " + tmp + "/x.png");
  CHECK(bad.code == 2);
  CHECK(has(bad.output, "--screenshot needs --frames N"));
  Result bad_resize = run_cli("view --backend cpu --frames 2 --resize 12x12");
  CHECK(bad_resize.code == 2);
  CHECK(has(bad_resize.output, "--resize '12x12': each side must be 16 to 8192 pixels"));
}
