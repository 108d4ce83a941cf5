#include "surface.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <numeric>
#include <random>
#include <ostream>
#include <sstream>
#include <stdexcept>

#include "sim.h"
#include "io/scene.h"
#include "pipeline/pipeline.h"
#include "pipeline/setup.h"

namespace sphray {

namespace {

constexpr double kPi = 3.14159265358979323846;

// A solver over the scene's grid holding `pts` at rest (jittered by up to
// `jitter` spacings each way, deterministically), with or without gravity.
std::unique_ptr<Solver> solver_of(const ResolvedScene& rs, Backend b, std::vector<Vec3f> pts, double jitter,
                                  bool gravity, PresenceMode presence) {
  SolverInput in = make_solver_input(rs, presence);
  if (!gravity) in.params.gravity = {0, 0, 0};
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const float amp = float(jitter * rs.scene.sph.spacing);
  in.fluid_pos_rho.clear();
  for (Vec3f p : pts) {
    if (amp > 0.0f) p = p + Vec3f{amp * u(rng), amp * u(rng), amp * u(rng)};
    in.fluid_pos_rho.push_back({p.x, p.y, p.z, in.params.rest_density});
  }
  in.fluid_vel.assign(pts.size(), Float4{0, 0, 0, 0});
  return b == Backend::Cuda ? make_cuda_solver(in) : make_cpu_solver(in);
}

SurfaceError in_spacings(SurfaceError e, double dx) {
  e.rms_distance /= dx;
  e.mean_distance /= dx;
  e.max_distance /= dx;
  return e;
}

}  // namespace

double pool_top_layer(const std::vector<Vec3f>& pos, double lo, double hi, int layers) {
  std::vector<double> z;
  for (const Vec3f& p : pos)
    if (p.x >= lo && p.x <= hi && p.y >= lo && p.y <= hi) z.push_back(p.z);
  if (z.empty()) return 0.0;
  const auto top = z.begin() + std::ptrdiff_t(std::max<size_t>(1, z.size() / size_t(std::max(layers, 1))));
  std::partial_sort(z.begin(), top, z.end(), std::greater<double>());
  return std::accumulate(z.begin(), top, 0.0) / double(top - z.begin());
}

std::string bench_surface_scene(int cells, int layers) {
  const double dx = 0.01, L = cells * dx, H = layers * dx;
  std::ostringstream os;
  os.precision(10);
  os << "{\"name\": \"bench_surface_" << cells << "\",\n"
     << " \"description\": \"a pool settling under gravity for sphray bench surface\",\n"
     << " \"tank\": {\"min\": [0, 0, 0], \"max\": [" << L << ", " << L << ", " << L << "]},\n"
     << " \"fluid\": [{\"min\": [0, 0, 0], \"max\": [" << L << ", " << L << ", " << H << "]}],\n"
     << " \"sph\": {\"spacing\": " << dx << ", \"solver\": \"dfsph\"},\n"
     << " \"field\": {\"refine\": 2},\n"
     << " \"run\": {\"end_time\": 10}}\n";
  return os.str();
}

std::vector<BenchSurfaceRow> bench_surface(Backend b, const BenchSurfaceOptions& opt, std::ostream& log) {
  const int cells = opt.cells > 0 ? opt.cells : (b == Backend::Cuda ? 64 : 24);
  const int layers = opt.layers > 0 ? opt.layers : cells / 2;
  if (layers > cells - 4)
    throw std::invalid_argument("bench surface: --layers " + std::to_string(layers) + " leaves less than 4 spacings of " +
                                "the " + std::to_string(cells) + "-spacing tank above the pool (at most " +
                                std::to_string(cells - 4) + ")");
  const ResolvedScene rs =
      resolve_scene(parse_scene(bench_surface_scene(cells, layers), "bench_surface", opt.overrides));
  const Scene& s = rs.scene;
  const double dx = s.sph.spacing, L = s.tank.max.x - s.tank.min.x;

  // The pool: lattice points, jittered, settled under gravity; its true
  // surface is the height its particles fill.
  const Vec3d c{0.5 * L, 0.5 * L, 0.5 * L};
  std::vector<Vec3f> lattice, ball, sheet;
  for (int k = 0; k < layers; ++k)
    for (int j = 0; j < cells; ++j)
      for (int i = 0; i < cells; ++i) lattice.push_back({float((i + 0.5) * dx), float((j + 0.5) * dx), float((k + 0.5) * dx)});
  auto pool = solver_of(rs, b, lattice, opt.jitter, true, PresenceMode::AtUntil);
  log << "  pool of " << pool->num_fluid() << " particles (jitter " << opt.jitter << " dx) settling for " << opt.settle
      << " s\n";
  log.flush();
  while (pool->time() < opt.settle - 1e-12) pool->step(opt.settle);
  const double height = double(pool->num_fluid()) * dx * dx * dx / (L * L);
  // The settled pool's particles do not fill N dx^3: the disordered packing
  // that SPH's density holds at rho0 is denser than the lattice (about 2%
  // at 24 across, docs/field.md). The second reference: the plane half a
  // spacing above the mean height of the top layer (the highest particle of
  // each column, counted over the rays' region), as the lattice's surface
  // lies half a spacing above its top layer.
  const double wall = 6 * dx;
  const double top_layer = pool_top_layer(pool->download().pos, wall, L - wall, layers);
  const double top_layer_dx = (height - 0.5 * dx - top_layer) / dx;
  log << "  settled pool: height " << height / dx << " spacings, top layer at " << top_layer / dx << " ("
      << top_layer_dx << " below the lattice's)\n";

  // A ball of particles (lattice points within 0.3 L of the tank's centre,
  // jittered), one step from rest without gravity: its true surface is the
  // sphere of the volume they fill.
  for (int k = 0; k < cells; ++k)
    for (int j = 0; j < cells; ++j)
      for (int i = 0; i < cells; ++i) {
        const double x = (i + 0.5) * dx, y = (j + 0.5) * dx, z = (k + 0.5) * dx;
        if ((x - c.x) * (x - c.x) + (y - c.y) * (y - c.y) + (z - c.z) * (z - c.z) < 0.09 * L * L)
          ball.push_back({float(x), float(y), float(z)});
      }
  // A sheet two particles thick (jittered), 4 spacings from the walls, at mid-height.
  const int edge = 4;
  for (int k = 0; k < 2; ++k)
    for (int j = edge; j < cells - edge; ++j)
      for (int i = edge; i < cells - edge; ++i)
        sheet.push_back({float((i + 0.5) * dx), float((j + 0.5) * dx), float(c.z + (k - 0.5) * dx)});
  const double ball_radius = std::cbrt(3.0 * double(ball.size()) / (4.0 * kPi)) * dx;
  auto ball_solver = solver_of(rs, b, ball, opt.jitter, false, PresenceMode::EveryStep);
  auto sheet_solver = solver_of(rs, b, sheet, opt.jitter, false, PresenceMode::EveryStep);
  ball_solver->step(1e-4);  // computes presence
  sheet_solver->step(1e-4);

  std::vector<BenchSurfaceRow> rows;
  for (FieldKernel kernel : {FieldKernel::Isotropic, FieldKernel::Anisotropic, FieldKernel::ZhuBridson})
    for (int refine : {0, 1, 2}) {
      ResolvedScene r = rs;
      r.scene.field.refine = refine;
      r.scene.field.kernel = kernel;
      const FieldSetup fs = make_field_setup(r);
      // Zhu & Bridson's surface has the gather builder alone.
      auto builder = make_field_builder(b, fs, fs.kernel == FieldKernel::ZhuBridson ? FieldKind::Gather : FieldKind::Presence);
      BenchSurfaceRow row;
      row.kernel = field_kernel_name(kernel);
      row.refine = refine;
      row.voxel_dx = fs.geom.voxel / dx;
      row.pool_particles = pool->num_fluid();
      row.pool_cells = cells;
      row.pool_layers = layers;
      row.sphere_particles = ball.size();
      row.sheet_particles = sheet.size();
      const ParticleView pv = pool->view();
      for (int k = 0; k < opt.warmup; ++k) builder->build(pv);
      std::vector<double> ms, ams;
      for (int k = 0; k < opt.frames; ++k) {
        builder->build(pv);
        ms.push_back(builder->last_ms());
        ams.push_back(builder->last_anisotropy_ms());
      }
      row.build_ms = median(ms);
      row.anisotropy_ms = median(ams);
      const float iso = fs.shape.iso;
      // Rays start 12 spacings outside each surface and stay 6 from the walls.
      const double margin = 12 * dx;
      const std::vector<float> field = builder->download();
      auto pool_error = [&](double plane) {
        return in_spacings(plane_surface_error(field, fs.geom, iso, {wall, wall, 0.0},
                                               {L - wall, L - wall, height + margin}, plane, 0.5 * dx),
                           dx);
      };
      row.pool = pool_error(height);
      row.pool_layer = pool_error(top_layer + 0.5 * dx);
      row.top_layer_dx = top_layer_dx;
      builder->build(ball_solver->view());
      row.sphere = in_spacings(sphere_surface_error(builder->download(), fs.geom, iso, c, ball_radius, 2000, margin), dx);
      builder->build(sheet_solver->view());
      const double in = (edge + 4) * dx;
      row.sheet = sheet_holes(builder->download(), fs.geom, iso, {in, in, c.z - 4 * dx}, {L - in, L - in, c.z + 4 * dx},
                              0.25 * dx);
      log << "    " << std::setw(12) << row.kernel << " refine " << refine << ": " << std::fixed << std::setprecision(3)
          << row.build_ms << " ms\n" << std::defaultfloat;
      log.flush();
      rows.push_back(row);
    }
  return rows;
}

nlohmann::json to_json(const std::vector<BenchSurfaceRow>& rows, Backend b, const BenchSurfaceOptions& opt) {
  nlohmann::json j = bench_json("surface", b, "median ms per build; errors in particle spacings", opt.overrides);
  j["warmup_builds"] = opt.warmup;
  j["measured_builds"] = opt.frames;
  j["settle_s"] = opt.settle;
  j["jitter_dx"] = opt.jitter;
  auto err = [](const SurfaceError& e) {
    return nlohmann::json{{"rays", e.rays},           {"missed", e.missed},
                          {"rms", e.rms_distance},    {"mean", e.mean_distance},
                          {"max", e.max_distance},    {"rms_angle_deg", e.rms_angle_deg},
                          {"max_angle_deg", e.max_angle_deg}};
  };
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows)
    j["rows"].push_back({{"kernel", r.kernel},
                         {"refine", r.refine},
                         {"voxel_in_spacings", r.voxel_dx},
                         {"particles", {{"pool", r.pool_particles}, {"sphere", r.sphere_particles}, {"sheet", r.sheet_particles}}},
                         {"pool_cells", r.pool_cells},
                         {"pool_layers", r.pool_layers},
                         {"build_ms", r.build_ms},
                         {"anisotropy_ms", r.anisotropy_ms},
                         {"pool", err(r.pool)},
                         {"pool_from_top_layer", err(r.pool_layer)},
                         {"top_layer_below_lattice_dx", r.top_layer_dx},
                         {"sphere", err(r.sphere)},
                         {"sheet", {{"rays", r.sheet.rays}, {"holes", r.sheet.holes}, {"hole_share", r.sheet.share()}}}});
  return j;
}

void print_table(const std::vector<BenchSurfaceRow>& rows, std::ostream& out) {
  out << std::setw(13) << "kernel" << std::setw(7) << "refine" << std::setw(7) << "voxel" << std::setw(9) << "ms"
      << std::setw(10) << "pool h" << std::setw(9) << "(mean)" << std::setw(9) << "layer h" << std::setw(9) << "(mean)"
      << std::setw(9) << "tilt" << std::setw(10) << "ball r"
      << std::setw(9) << "(mean)" << std::setw(9) << "normal" << std::setw(9) << "holes%" << "\n";
  for (const auto& r : rows)
    out << std::setw(13) << r.kernel << std::setw(7) << r.refine << std::fixed << std::setprecision(2) << std::setw(7)
        << r.voxel_dx << std::setprecision(3) << std::setw(9) << r.build_ms << std::setw(10) << r.pool.rms_distance
        << std::setw(9) << r.pool.mean_distance << std::setw(9) << r.pool_layer.rms_distance << std::setw(9)
        << r.pool_layer.mean_distance << std::setprecision(2) << std::setw(9) << r.pool.rms_angle_deg
        << std::setprecision(3) << std::setw(10) << r.sphere.rms_distance << std::setw(9) << r.sphere.mean_distance
        << std::setprecision(2) << std::setw(9) << r.sphere.rms_angle_deg << std::setw(9) << 100.0 * r.sheet.share()
        << std::defaultfloat << "\n";
  out << "  (voxel edge, pool height and ball radius errors in particle spacings, RMS and mean (+: outside); layer h:\n"
         "   the pool against the plane half a spacing above its top layer of particles; tilt\n"
         "   and normal: RMS angle from the true normal [degrees]; holes: share of rays through the two-particle sheet\n"
         "   that meet no liquid; ms: median build time on the pool, by the presence builder with the covariance pass\n"
         "   included, zhu_bridson by the gather builder)\n";
}

}  // namespace sphray
