// Quantities measured on a particle state, and their comparison with
// experiments: the surge front of a dam break (Martin & Moyce 1952).
#pragma once

#include <string>
#include <vector>

#include "mesh/mesh.h"
#include "sph/solver.h"

namespace sphray {

// Leading edge of the liquid along +x, measured from back_wall_x [m]: the
// foremost particle centre plus half a spacing (a particle's own extent), so a
// column of width a at rest reads exactly a.
double surge_front(const HostParticles& p, double back_wall_x, double spacing);
// The same from the particles' sums (Solver::flow_sums).
double surge_front(const FlowSums& f, double back_wall_x, double spacing);

double kinetic_energy(const HostParticles& p, double particle_mass);
double kinetic_energy(const FlowSums& f, double particle_mass);

// The force of the liquid's pressure on an obstacle, -sum p A n over its
// surface (n outward), and the share of that surface the liquid wets. The
// pressure at a point of the surface is the kernel-weighted pressure of the
// fluid particles around it plus their hydrostatic difference to it,
//   p(x) = (sum_f p_f W + g . sum_f rho_f (x - x_f) W) / sum_f W,
// the extrapolation that Adami et al. (2012) give the wall particles
// (sph/boundary.h); the surface is sampled at points at most half a spacing
// apart. `pressure` holds p_f per particle of `p` (WCSPH: tait_pressure of
// its density; DFSPH: Solver::pressures()).
struct ObstacleForce {
  Vec3d force{0, 0, 0};  // [N]
  double wetted = 0;     // share of the area with liquid within the kernel's support
};
ObstacleForce obstacle_force(const TriangleMesh& mesh, const HostParticles& p, const std::vector<float>& pressure,
                             const SmoothingKernel<double>& kernel, Vec3d gravity, double spacing);

// The height of the liquid on the vertical line through (x, y), measured as
// the highest point of that line, from the floor z_floor up, where the
// kernel sum of the particles' volumes sum_f V W(|z - x_f|) (the share of
// space the liquid fills; 1 inside, 1/2 at a resting surface) is at least
// 1/2; sampled every quarter spacing. 0 where the line is dry. Splashes
// above a gap count, as a gauge that is wetted there would.
double water_height(const HostParticles& p, double x, double y, const SmoothingKernel<double>& kernel, double volume,
                    double z_floor, double z_top, double spacing);

struct Curve {
  std::vector<double> x, y;
};

// Reads a two-column CSV (lines starting with '#' and one header line skipped).
Curve read_csv_curve(const std::string& path);

// Linear interpolation of a curve sampled at increasing x; clamps at the ends.
double interpolate(const Curve& c, double x);

// RMS of (sim(T) - exp(T)) / exp(T) over the experimental points with T <= sim's last T.
struct CurveError {
  double rms_relative = 0, max_relative = 0;
  size_t points = 0;
};
CurveError relative_error(const Curve& sim, const Curve& experiment);

// A density field against a reference field (the naive builder's), both on
// the same nx x ny x nz voxels, classified inside where value >= iso
// (docs/field.md, "Error"):
// - misclassified share: voxels whose inside/outside differs, over the voxels
//   within two voxels (Chebyshev) of the reference surface (a voxel with a
//   face neighbour on the other side); differences farther away (holes, say)
//   are counted separately;
// - distance between the iso-surfaces in voxels: the surface points where the
//   field crosses iso along voxel edges (linear interpolation, as a trilinear
//   sampler sees it), each matched to the nearest point of the other surface,
//   both ways; mean and max (capped at kMaxSurfaceDistance voxels, beyond which
//   a point counts as unmatched).
struct FieldError {
  static constexpr double kMaxSurfaceDistance = 4.0;
  uint64_t band = 0, misclassified_band = 0, misclassified_other = 0;
  uint64_t ref_points = 0, test_points = 0, unmatched = 0;
  double mean_distance = 0, max_distance = 0;
  double misclassified_share() const { return band ? double(misclassified_band) / double(band) : 0.0; }
};
FieldError compare_fields(int nx, int ny, int nz, const std::vector<float>& ref, const std::vector<float>& test,
                          float iso);

}  // namespace sphray
