// The sphray executable end to end: exit codes and messages for bad input,
// a short run that succeeds.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>

#include "catch.h"
#include "helpers.h"

namespace {

struct Result {
  int code;
  std::string output;
};

Result run_cli(const std::string& args) {
  const std::string out = "/tmp/sphray_cli_test.txt";
  const std::string cmd = std::string(SPHRAY_EXE) + " " + args + " > " + out + " 2>&1";
  const int status = std::system(cmd.c_str());
  std::ifstream f(out);
  std::stringstream ss;
  ss << f.rdbuf();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ss.str()};
}

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("sphray run reports bad input with exit code 2", "[cli][cpu]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  Result r = run_cli("run /nonexistent.json --backend cpu");
  CHECK(r.code == 2);
  CHECK(has(r.output, "cannot open scene file"));

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

  std::ofstream("/tmp/sphray_bad.json") << "{\"tank\": [1,2";
  r = run_cli("run /tmp/sphray_bad.json --backend cpu");
  CHECK(r.code == 2);
  CHECK(has(r.output, "not valid JSON"));
}

TEST_CASE("sphray run simulates a small scene and prints a summary", "[cli][cpu]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  const Result r = run_cli("run " + scene + " --backend auto --set run.end_time=0.05 --set run.output_interval=0.01 --metrics-csv /tmp/sphray_m.csv");
  CHECK(r.code == 0);
  CHECK(has(r.output, "backend: "));
  CHECK(has(r.output, "summary"));
  CHECK(has(r.output, "8 fluid at start, 8 at end"));
  std::ifstream csv("/tmp/sphray_m.csv");
  std::string header, line;
  std::getline(csv, header);
  CHECK(has(header, "front_m"));
  int rows = 0;
  while (std::getline(csv, line)) ++rows;
  CHECK(rows == 6);  // t = 0 and five output intervals of 0.01 s
}

TEST_CASE("sphray run builds the field at every frame when the scene has one", "[cli][cpu]") {
  const std::string scene = sphray::test::source_path("scenes/stress/one_cell.json");
  const Result r = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.02 --set run.output_interval=0.01 "
                           "--set field.builder=presence --summary-json /tmp/sphray_field_summary.json");
  INFO(r.output);
  CHECK(r.code == 0);
  CHECK(has(r.output, "field          presence builder"));
  CHECK(has(r.output, "3 builds"));               // t = 0 and two frames
  CHECK(has(r.output, "1 without presence"));     // only t = 0: the frames' last steps computed it
  std::ifstream f("/tmp/sphray_field_summary.json");
  std::stringstream ss;
  ss << f.rdbuf();
  CHECK(has(ss.str(), "\"builds_without_presence\": 1"));
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
  r = run_cli("run " + scene + " --backend cpu --quiet --export /tmp/x.h5 --export-fields velocity,colour");
  CHECK(r.code == 2);
  CHECK(has(r.output, "unknown field 'colour'"));
  r = run_cli("inspect /nonexistent.h5");
  CHECK(r.code == 2);
  CHECK(has(r.output, "missing or unreadable"));
  std::ofstream("/tmp/sphray_cli_text.h5") << "plain text";
  r = run_cli("inspect /tmp/sphray_cli_text.h5");
  CHECK(r.code == 2);
  CHECK(has(r.output, "not an HDF5 file"));

  r = run_cli("run " + scene + " --backend cpu --quiet --set run.end_time=0.02 --set run.output_interval=0.01 "
              "--export /tmp/sphray_cli.h5 --export-every 2 --export-fields density");
  CHECK(r.code == 0);
  CHECK(has(r.output, "2 frames to /tmp/sphray_cli.h5"));  // t = 0 and t = 0.02
  r = run_cli("inspect /tmp/sphray_cli.h5");
  CHECK(r.code == 0);
  CHECK(has(r.output, "frames 2"));
  CHECK(has(r.output, "000001  t = 0.02 s"));
  CHECK(has(r.output, "density ["));
}
