// `sphray bench surface`: how close the rendered surface is to the true one,
// for each kernel (spheres, anisotropic ellipsoids) and refine level, against
// its build time (docs/field.md, "Surface error"). Three liquids whose
// surface is known: a pool settled under gravity (a plane at the height its
// particles fill; also half a spacing above its top layer), a ball of
// particles without gravity (a sphere of the volume they fill), and a sheet
// two particles thick (no holes).
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/device.h"
#include "core/vec.h"
#include "io/surface_error.h"

namespace sphray {

struct BenchSurfaceOptions {
  int cells = 0;        // pool width in particles: 0 = 64 on CUDA, 24 on CPU
  int layers = 0;       // pool depth in particle layers: 0 = half its width
  double settle = 1.0;  // seconds the pool settles under gravity (DFSPH)
  double jitter = 0.1;  // pool and ball start from the lattice moved up to this many spacings each way
  int warmup = 3, frames = 10;
  std::vector<std::string> overrides;  // --set on the generated scene (field.*, e.g. field.anisotropy.stretch=3)
};

struct BenchSurfaceRow {
  std::string kernel;  // isotropic, anisotropic
  int refine = 0;
  double voxel_dx = 0;  // voxel edge in particle spacings
  size_t pool_particles = 0, sphere_particles = 0, sheet_particles = 0;
  int pool_cells = 0, pool_layers = 0;  // the pool's width and depth in particles (the options resolved)
  double build_ms = 0, anisotropy_ms = 0;  // pool field, presence builder: median, and its covariance pass
  SurfaceError pool, sphere;               // distances in particle spacings
  // The pool against the plane half a spacing above its top layer of
  // particles (bench_surface: the settled pool fills less than N dx^3).
  SurfaceError pool_layer;
  double top_layer_dx = 0;  // the top layer's mean height below H - dx / 2 [spacings]
  SheetHoles sheet;
};

// The mean height of a pool's top layer: of the particles within [lo, hi] in
// x and y, the highest one per column of a pool `layers` particles deep (so
// their count / layers of them).
double pool_top_layer(const std::vector<Vec3f>& pos, double lo, double hi, int layers);

// The generated pool scene (JSON text): `cells` particles across, `layers` deep.
std::string bench_surface_scene(int cells, int layers);

std::vector<BenchSurfaceRow> bench_surface(Backend b, const BenchSurfaceOptions& opt, std::ostream& log);
nlohmann::json to_json(const std::vector<BenchSurfaceRow>& rows, Backend b, const BenchSurfaceOptions& opt);
void print_table(const std::vector<BenchSurfaceRow>& rows, std::ostream& out);

}  // namespace sphray
