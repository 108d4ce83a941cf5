// `sphray bench field`: the naive, presence and gather field builders on the
// same particles (Yasuda et al.'s Table 1 and beyond): a dam break simulated
// until its column has collapsed, then each builder timed over many frames
// (device events after warm-up, medians), its work counted in one extra
// build, and its field compared with the naive one (metrics.h, FieldError).
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/kernel_times.h"
#include "field/field.h"
#include "io/metrics.h"
#include "io/scene.h"
#include "sph/solver.h"

namespace sphray {

struct BenchFieldOptions {
  std::vector<size_t> sizes;  // target fluid particle counts
  int volume = 0;             // volume edge in voxels: 0 = 64 up to 200k particles, else 256
  int warmup = 5;
  int frames = 30;
  double collapse = 2.5;      // fields are built at T = t sqrt(2g/a) = collapse (front near 3a)
  std::vector<std::string> overrides;  // --set key.path=value on the generated scene (field.*, sph.*)
  bool kernels = false;  // also time every named launch (ms per build by name, over further builds)
};

struct BenchFieldRow {
  size_t particles = 0;
  int nx = 0, ny = 0, nz = 0;
  std::string builder;  // naive, presence (default layouts), naive-thread/-8/-warp, presence-thread/-4/-8/-warp (1, 4, 8, 32
                        // threads per particle), presence-full (unshrunk extents), gather
  double median_ms = 0, min_ms = 0, max_ms = 0;
  FieldCounts counts;
  FieldError error;  // against naive
  double sim_time = 0;
  std::vector<KernelTime> kernels;  // ms per build by launch name (--kernels)
};

// The generated scene of one size (JSON text), for the record and for tests.
std::string bench_field_scene(size_t particles, int volume);
// The same tank and spacing with the particles as a still pool over the
// whole floor (for bench render).
std::string bench_pool_scene(size_t particles, int volume);
// The volume edge used when none is asked for: 64 up to 200k particles, else 256.
int default_bench_volume(size_t particles);
// Simulates the generated scene's column to T = t sqrt(2g/a) = collapse, the
// step that reaches it computing presence; logs what it does (`what`: more about the run, e.g. the volume).
void simulate_collapse(const Scene& s, Solver& solver, double collapse, std::ostream& log, const std::string& what = "");

std::vector<BenchFieldRow> bench_field(Backend b, const BenchFieldOptions& opt, std::ostream& log);
nlohmann::json to_json(const std::vector<BenchFieldRow>& rows, Backend b, const BenchFieldOptions& opt);
void print_table(const std::vector<BenchFieldRow>& rows, std::ostream& out);

}  // namespace sphray
