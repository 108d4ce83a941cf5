// Shared test helpers: small scenes in JSON text, and running a solver to a time.
#pragma once

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "pipeline/pipeline.h"
#include "io/scene.h"
#include "nsearch_probe.h"
#include "mesh/mesh.h"
#include "pipeline/setup.h"
#include "sph/solver.h"

namespace sphray::test {

inline std::string source_path(const std::string& rel) { return std::string(SPHRAY_SOURCE_DIR) + "/" + rel; }

// The solver's FlowSums (reduced on its backend) against the same sums over
// its downloaded particles, in double on the host: the largest x exactly,
// the sum of squared speeds to the summation order's round-off.
inline void check_flow_sums(const Solver& s) {
  const HostParticles p = s.download();
  double max_x = -1e300, speed2 = 0;
  for (size_t i = 0; i < p.pos.size(); ++i) {
    max_x = std::max(max_x, double(p.pos[i].x));
    speed2 += double(p.vel[i].x) * p.vel[i].x + double(p.vel[i].y) * p.vel[i].y + double(p.vel[i].z) * p.vel[i].z;
  }
  const FlowSums f = s.flow_sums();
  INFO(p.pos.size() << " particles: max x " << f.max_x << " against " << max_x << ", sum v^2 " << f.speed2_sum
                    << " against " << speed2);
  CHECK(f.max_x == max_x);
  CHECK(std::abs(f.speed2_sum - speed2) <= 1e-9 * speed2);
}

// The backend's three-way split of n indices by random classes (half of
// class 0, about a third of class 1, the rest 2, and runs of one class as
// the grid order gives) against the lists made by hand: the first two in
// index order, the rest as a set.
inline void check_partition_three(Backend b, uint32_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<uint8_t> cls(n);
  std::vector<uint32_t> want[3];
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t r = rng() % 100;
    cls[i] = uint8_t(i % 5000 < 700 ? 1 : r < 50 ? 0 : r < 83 ? 1 : 2);
    want[cls[i]].push_back(i);
  }
  PartitionBuild got = partition_three(b, cls);
  CHECK(got.first == want[0]);
  CHECK(got.second == want[1]);
  std::sort(got.rest.begin(), got.rest.end());
  CHECK(got.rest == want[2]);
}

// This test process's own directory for the files it writes, made on first
// use under $TMPDIR (or /tmp) and removed when the process ends, so that
// test processes run side by side (ctest -j) never share a path.
class TempDir {
 public:
  TempDir() {
    const char* base = std::getenv("TMPDIR");
    std::string pattern = std::string(base && *base ? base : "/tmp") + "/sphray-test-XXXXXX";
    if (!mkdtemp(pattern.data())) throw std::runtime_error("cannot make a temporary directory " + pattern);
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};
inline const std::string& tmp_dir() {
  static const TempDir dir;
  return dir.path();
}

inline bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// A whole file's bytes ("" when it cannot be read).
inline std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// The sphray executable run with `args`: its exit code (-1 if it did not
// exit) and its stdout and stderr together.
struct CliResult {
  int code;
  std::string output;
};
inline CliResult run_cli(const std::string& args) {
  const std::string out = tmp_dir() + "/cli_output.txt";
  const int status = std::system((std::string(SPHRAY_EXE) + " " + args + " > " + out + " 2>&1").c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out)};
}

// Within the scene's tank (walls included).
inline bool inside(const Vec3f& p, const Scene& s) {
  return p.x >= s.tank.min.x && p.y >= s.tank.min.y && p.z >= s.tank.min.z && p.x <= s.tank.max.x &&
         p.y <= s.tank.max.y && p.z <= s.tank.max.z;
}

// Within the tank as the solver holds it in single precision (SphParams::tank,
// walls included): where a projection onto a wall leaves a particle.
inline bool inside(const Vec3f& p, const Aabb& tank) {
  return p.x >= tank.min.x && p.y >= tank.min.y && p.z >= tank.min.z && p.x <= tank.max.x && p.y <= tank.max.y &&
         p.z <= tank.max.z;
}

// The message of the SceneError that parsing `text` (with --set overrides)
// raises, or "" if it parses.
// A closed, outward-wound torus (genus 1) about the z axis, radii 1 and 0.3.
inline TriangleMesh torus_mesh(const std::string& name) {
  TriangleMesh torus;
  torus.name = name;
  const int nu = 24, nv = 12;
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
      torus.vertices.push_back(
          {(1 + 0.3 * std::cos(v)) * std::cos(u), (1 + 0.3 * std::cos(v)) * std::sin(u), 0.3 * std::sin(v)});
    }
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const uint32_t a = i * nv + j, b = ((i + 1) % nu) * nv + j, c = ((i + 1) % nu) * nv + (j + 1) % nv,
                     d = i * nv + (j + 1) % nv;
      torus.triangles.push_back({a, b, c});
      torus.triangles.push_back({a, c, d});
    }
  if (signed_volume(torus) < 0) flip(torus);
  return torus;
}

inline std::string scene_error(const std::string& text, const std::vector<std::string>& sets = {}) {
  try {
    parse_scene(text, "t.json", sets);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

// The field the CPU builder of `kind` makes from a particle view.
inline std::vector<float> cpu_field(const FieldSetup& fs, const ParticleView& v, FieldKind kind) {
  auto b = make_cpu_field_builder(fs, kind);
  b->build(v);
  return b->download();
}

// The tank's walls as mirrors, made by hand from their planes (independent of
// sph/mirror_walls.h) for the double references of the field's sums: the
// walls within `reach` of x, the nearer one per axis (an open top is none).
struct HandMirrors {
  double plane[3] = {0, 0, 0};
  bool near[3] = {false, false, false};
  HandMirrors(const FieldWalls& walls, double reach, const double x[3]) {
    const double lo[3] = {walls.tank.min.x, walls.tank.min.y, walls.tank.min.z},
                 hi[3] = {walls.tank.max.x, walls.tank.max.y, walls.tank.max.z};
    for (int a = 0; a < 3; ++a) {
      const bool low = walls.mirror, high = walls.mirror && !(a == 2 && walls.open_top);
      const double d_lo = x[a] - lo[a], d_hi = hi[a] - x[a];
      const bool near_lo = low && d_lo < reach, near_hi = high && d_hi < reach;
      if (near_lo && (!near_hi || d_lo <= d_hi)) { plane[a] = lo[a]; near[a] = true; }
      else if (near_hi) { plane[a] = hi[a]; near[a] = true; }
    }
  }
  // f(q) for p itself and for its image across each non-empty subset of the near walls.
  template <class F>
  void each(const Vec3f& p, F&& f) const {
    for (int set = 0; set < 8; ++set) {
      bool ok = true;
      double q[3] = {p.x, p.y, p.z};
      for (int a = 0; a < 3; ++a) {
        if (!(set >> a & 1)) continue;
        ok = ok && near[a];
        q[a] = 2 * plane[a] - q[a];
      }
      if (ok) f(q);
    }
  }
};

inline void run_until(Solver& s, double t) {
  while (s.time() < t - 1e-12) s.step(t);
}

// The message of the SimulationError that one step(until) raises, or "" if
// it raises none.
inline std::string step_error(Solver& s, double until) {
  try {
    s.step(until);
  } catch (const SimulationError& e) {
    return e.what();
  }
  return {};
}

// Steps to `until`; the error that stopped the run, if any.
inline std::string run_to_error(Solver& s, double until) {
  std::string e;
  while (e.empty() && s.time() < until - 1e-12) e = step_error(s, until);
  return e;
}

// One particle dropped from 0.3 m in a 0.4 m tall tank, to t = 0.4 s, with
// the speed of sound c0 [m/s]: the scene check takes sqrt(g H) = 1.73 m/s
// (H = 0.305 m, its top above the floor) as the speed it can reach.
inline Scene dropped_particle_scene(double c0) {
  const std::string text = R"({"tank": {"min": [0,0,0], "max": [0.1,0.1,0.4]},
    "fluid": [{"min": [0.045,0.045,0.295], "max": [0.055,0.055,0.305]}],
    "sph": {"spacing": 0.01}, "run": {"end_time": 0.4}})";
  return parse_scene(text, "drop.json", {"sph.speed_of_sound=" + std::to_string(c0)});
}

// Eight particles shot up at 20 m/s in a tank without a lid: all of them
// leave through the top before t = 0.1 s.
inline Scene open_top_jet_scene() {
  const std::string text = R"({"tank": {"min": [0,0,0], "max": [0.1,0.1,0.1], "open_top": true},
    "fluid": [{"min": [0.04,0.04,0.02], "max": [0.06,0.06,0.04], "velocity": [0,0,20]}],
    "sph": {"spacing": 0.01}, "run": {"end_time": 0.1}})";
  return parse_scene(text, "open.json");
}

}  // namespace sphray::test
