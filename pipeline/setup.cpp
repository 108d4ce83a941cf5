#include "setup.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>

#include "field/anisotropy.h"
#include "mesh/bvh.h"
#include "nsearch/pair_masks.h"
#include "sph/eos.h"
#include "sph/lattice.h"
#include "sph/pbf_lattice.h"
#include "sph/pbf_weights.h"
#include "sph/skin.h"

namespace sphray {

namespace {

int lattice_count(double size, double dx) { return std::max(1, int(std::floor(size / dx + 1e-6))); }

// Overlapping fluid blocks fill their union once: a particle of block b is
// left out where an earlier block already has liquid, i.e. when it lies
// inside an earlier block's box or less than half a spacing outside it (the
// earlier block's outermost particles sit half a spacing to one spacing inside
// its faces, so what is kept stays at least 3/4 of a spacing from them).
// Blocks whose corners share one dx lattice join with no seam.
bool covered_before(const std::vector<FluidBlock>& blocks, size_t b, Vec3d p, double dx) {
  const double m = 0.49 * dx;
  for (size_t a = 0; a < b; ++a) {
    const Box& q = blocks[a].box;
    if (p.x > q.min.x - m && p.x < q.max.x + m && p.y > q.min.y - m && p.y < q.max.y + m && p.z > q.min.z - m &&
        p.z < q.max.z + m)
      return true;
  }
  return false;
}

// The free surface above a particle of block `own` at p, as a height along
// `up`: the top of its own block, raised through every block stacked on it
// (one that the vertical line through p enters at or below the surface found
// so far, within half a spacing), so that a column standing on a bed of
// liquid starts with the bed's particles under it at the column's full depth.
double surface_above(const std::vector<FluidBlock>& blocks, size_t own, Vec3d p, Vec3d up, double dx) {
  const double base = dot(p, up);
  double surface = box_top(blocks[own].box, up);
  for (bool raised = true; raised;) {
    raised = false;
    for (const auto& blk : blocks) {
      double t_in, t_out;  // along the vertical through p (ray_box: a box wholly below p is no hit)
      if (!ray_box(p, up, blk.box.min, blk.box.max, t_in, t_out)) continue;
      if (base + t_in <= surface + 0.5 * dx && base + t_out > surface + 1e-12 * dx) {
        surface = base + t_out;
        raised = true;
      }
    }
  }
  return surface;
}

struct AxisCoords {
  std::vector<double> c;
  size_t wall_lo, inner;  // c = [wall_lo lower-wall coords][inner coords][upper-wall coords]
};

AxisCoords axis_coords(double lo, double hi, double dx, int layers, bool upper_wall) {
  AxisCoords a;
  for (int l = layers - 1; l >= 0; --l) a.c.push_back(lo - (l + 0.5) * dx);
  a.wall_lo = a.c.size();
  const int n = std::max(1, int(std::lround((hi - lo) / dx)));
  const double s = (hi - lo) / n;
  for (int k = 0; k < n; ++k) a.c.push_back(lo + (k + 0.5) * s);
  a.inner = size_t(n);
  if (upper_wall)
    for (int l = 0; l < layers; ++l) a.c.push_back(hi + (l + 0.5) * dx);
  return a;
}

bool is_wall(const AxisCoords& a, size_t k) { return k < a.wall_lo || k >= a.wall_lo + a.inner; }

// An obstacle's mesh on the host, for the setup's point queries.
struct ObstacleProbe {
  std::unique_ptr<Bvh> tree;
  Box box;
  explicit ObstacleProbe(const TriangleMesh& m) : box(bounds(m)) {
    const MeshInput in = mesh_input(m);
    tree = make_cpu_bvh(in.vertices, in.indices);
  }
  // Inside the closed mesh: an odd count of crossings, by the majority of
  // three rays (one grazing an edge or a vertex can count wrongly).
  bool inside(Vec3d p) const {
    if (p.x < box.min.x || p.y < box.min.y || p.z < box.min.z || p.x > box.max.x || p.y > box.max.y || p.z > box.max.z)
      return false;
    static const Vec3f dirs[3] = {{0.5773f, 0.5774f, 0.5775f}, {-0.6f, 0.64f, 0.48f}, {0.28f, -0.96f, 0.0f}};
    const MeshView v = tree->view();
    int odd = 0;
    for (const Vec3f& d : dirs) odd += int(count_crossings(v, to_f(p), d) & 1u);
    return odd >= 2;
  }
  // Distance to the surface when below r (else r).
  double distance(Vec3d p, double r) const {
    uint32_t slot = 0;
    const float r2 = float(r * r), d2 = nearest_distance2(tree->view(), to_f(p), r2, slot);
    return d2 < r2 ? std::sqrt(double(d2)) : r;
  }
};

std::vector<ObstacleProbe> obstacle_probes(const Scene& s) {
  std::vector<ObstacleProbe> out;
  for (const Obstacle& o : s.obstacles) out.emplace_back(o.mesh);
  return out;
}

// A fluid lattice point that an obstacle takes: inside it, or nearer its
// surface than half a spacing (the fluid keeps from a mesh the distance it
// keeps from the tank's faces; 0.49: a point half a spacing off stays).
bool in_obstacle(const std::vector<ObstacleProbe>& probes, Vec3d p, double dx) {
  for (const ObstacleProbe& o : probes)
    if (o.inside(p) || o.distance(p, 0.49 * dx) < 0.49 * dx) return true;
  return false;
}

// One presence lobe (sph/interaction.h) of a node inside a full lattice,
// with particle volume V: sum over the half space x < 0 of V (-dW/dr / r) |x|.
template <class K>
double presence_lobe_on_lattice(const K& k, double dx, double volume) {
  double sum = 0;
  for_lattice_neighbours(k.support(), dx, [&](int x, int, int, double r) {
    if (x < 0) sum += volume * -k.dW_over_r(r) * (-x * dx);
  });
  return sum;
}

// The height of the scene's liquid above the tank floor along gravity
// (at least one spacing), as expected_flow_speed measures it.
double depth_of(const Scene& s) {
  const Vec3d up = up_of(s);
  const double floor = -box_top(s.tank, up * -1.0);
  double top = floor;
  for (const auto& b : s.fluid) top = std::max(top, box_top(b.box, up));
  return std::max(top - floor, s.sph.spacing);
}

// The largest decay rate per unit viscosity [1 / m^2] of DFSPH's explicit
// viscosity (dfsph.h, DfsphViscosity) at a particle beside a wall: the
// lattice's bound (lattice_viscous_rate_bound) plus the particle's own
// image. The image lies 2 d away and moves with the particle's velocity
// reversed (no-slip; free-slip: its normal component), so that it damps v_i
// at 2 (d + 2) V 2 |dW/dr / r| (2 d)^2 / ((2 d)^2 + eta2) on its own: at the
// default support and wall margin (d = 0.1 dx) 0.7 times the bulk's bound
// with the cubic spline, 1.3 times with Wendland C2. The largest over the
// distances from the wall margin to half the support.
double dfsph_viscous_rate_bound(const SmoothingKernel<double>& k, double dx, double volume, double margin) {
  const double eta2 = 0.01 * k.h * k.h;
  const double bulk = lattice_viscous_rate_bound(k.support(), dx, volume, eta2, [&](double r) { return k.dW_over_r(r); });
  double own = 0;
  for (int i = 0; i <= 64; ++i) {
    const double r = 2.0 * (margin + (0.5 * k.support() - margin) * i / 64.0);
    if (r <= 0) continue;
    own = std::max(own, 2.0 * 10.0 * volume * -k.dW_over_r(r) * r * r / (r * r + eta2));
  }
  return bulk + own;
}

}  // namespace

MeshInput mesh_input(const TriangleMesh& m) {
  MeshInput in;
  in.vertices.reserve(m.vertices.size());
  for (const Vec3d& v : m.vertices) in.vertices.push_back(to_f(v));
  in.indices.reserve(3 * m.triangles.size());
  for (const auto& t : m.triangles) in.indices.insert(in.indices.end(), t.begin(), t.end());
  return in;
}

std::vector<MeshInput> obstacle_meshes(const Scene& s) {
  std::vector<MeshInput> out;
  for (const Obstacle& o : s.obstacles) {
    out.push_back(mesh_input(o.mesh));
    out.back().motion = o.motion;
  }
  return out;
}

std::vector<SkinInput> skin_inputs(const Scene& s) {
  std::vector<SkinInput> out;
  for (size_t k = 0; k < s.obstacles.size(); ++k) {
    const Obstacle& o = s.obstacles[k];
    if (o.has_skin) out.push_back({uint32_t(k), o.mesh, o.motion, o.skin, o.skin_embedding});
  }
  return out;
}

std::vector<MeshInput> drawn_obstacles(std::vector<MeshInput> meshes, const std::vector<SkinGeometry>& skins) {
  for (const SkinGeometry& g : skins) {
    const Motion motion = meshes[g.input.obstacle].motion;
    meshes[g.input.obstacle] = mesh_input(g.surface.mesh);
    meshes[g.input.obstacle].motion = motion;
  }
  return meshes;
}

std::vector<MeshInput> drawn_obstacles(std::vector<MeshInput> meshes, const Solver& solver) {
  const SkinSet* skins = solver.skins();
  if (!skins) return meshes;
  return drawn_obstacles(std::move(meshes), skins->geometries());
}

void show_skins(const Solver& solver, Renderer& renderer) {
  const SkinSet* skins = solver.skins();
  for (size_t k = 0; skins && k < skins->size(); ++k)
    renderer.set_obstacle_vertices(skins->geometry(k).input.obstacle, skins->displaced(k));
}

SphParams make_params(const Scene& s) {
  SphParams p{};
  const double dx = s.sph.spacing;
  const SmoothingKernel<double> kernel = s.sph.smoothing_kernel();
  p.kernel = SmoothingKernel<float>::make(s.sph.kernel, float(kernel.h));
  p.rest_density = float(s.sph.rest_density);
  p.particle_mass = float(s.sph.rest_density * dx * dx * dx);
  double c0 = s.sph.speed_of_sound;
  if (c0 <= 0) c0 = auto_speed_of_sound(s);  // weakly compressible: 10x the expected flow speed (scene.h)
  p.speed_of_sound = float(c0);
  p.tait_b = float(tait_b(c0, s.sph.rest_density));
  p.viscosity_alpha = float(s.sph.viscosity_alpha);
  p.density_diffusion = float(s.sph.density_diffusion);
  p.gravity = to_f(s.gravity);
  p.spacing = float(dx);
  p.tank = {to_f(s.tank.min), to_f(s.tank.max)};
  p.open_top = s.open_top;
  p.presence_scale = float(0.5 / presence_lobe_on_lattice(kernel, dx));
  return p;
}

double presence_lobe_on_lattice(const SmoothingKernel<double>& k, double dx) {
  return presence_lobe_on_lattice(k, dx, dx * dx * dx);
}

PbfParams make_pbf_params(const Scene& s) {
  const PbfConfig& c = s.sph.pbf;
  const double dx = s.sph.spacing;
  const PbfKernel<double> k = PbfKernel<double>::make(c.support * dx);
  // The relaxation and s_corr are given as shares of G0 (pbf_lattice.h).
  const PbfLatticeScales scales = pbf_lattice_scales(k, dx);
  const double volume = scales.volume, g0 = scales.g0;
  const double dq = c.scorr_dq * k.support();
  PbfParams p{};
  p.kernel = PbfKernel<float>::make(float(k.support()));
  p.volume = float(volume);
  p.epsilon = float(c.relaxation * g0);
  p.scorr_coef = float(c.scorr_k / g0);
  p.inv_w_dq = float(1.0 / k.W(dq * dq));
  p.scorr_n = c.scorr_n;
  p.max_correction = float(c.max_correction * dx);
  p.wall_margin = float(c.wall_margin * dx);
  p.xsph = float(c.xsph);
  p.mirrored_images = c.mirrored_images;
  p.rest_weights = 0;
  if (c.rest_chebyshev) {
    // Over more iterations than kRestWeights the schedule of kRestWeights repeats.
    const double top = PbfRestSpectrum::top(
        lattice_spectrum_bound(k.support(), dx, [&](double r) { return k.dW_over_r(r); }), c.relaxation);
    const std::vector<double> w = pbf_rest_weights(std::min(c.iterations, PbfParams::kRestWeights), top);
    p.rest_weights = int(w.size());
    for (size_t i = 0; i < w.size(); ++i) p.rest_weight[i] = float(w[i]);
  }
  p.vorticity = float(c.vorticity);
  p.presence_scale = float(0.5 / presence_lobe_on_lattice(k, dx, volume));
  // The flow speed the scene can reach, sqrt(g H) (or its fastest initial
  // velocity), and from the same H the depth limit of ChooseFlowStep: the
  // step at which g H dt^2 / (K s^2), the compression a column of depth H
  // keeps when K Jacobi iterations carry the constraint through it, is
  // pbf.depth_error.
  // Without gravity nothing compresses a column: no depth limit; nor where
  // the scene turns it off (pbf.depth_error = 0).
  const double v = expected_flow_speed(s), g = length(s.gravity);
  p.speed_floor = float(v);
  p.max_dt_depth = g > 0 && c.depth_error > 0
                       ? float(k.support() * std::sqrt(c.iterations * c.depth_error / (g * depth_of(s))))
                       : std::numeric_limits<float>::max();
  p.step_error = float(c.step_error);
  // A flowing liquid's target: at least the one at rest.
  p.step_error_flow = c.step_error_flow > 0 ? float(std::max(c.step_error_flow, c.step_error)) : 0.0f;
  p.flow_speed = float(c.flow_speed * v);
  p.iterations = c.iterations;
  p.tolerance = float(c.tolerance);
  return p;
}

double auto_dfsph_viscosity(const Scene& s) {
  const SphConfig wcsph;  // the defaults
  return wcsph.viscosity_alpha * wcsph.smoothing_ratio * s.sph.spacing * auto_speed_of_sound(s) / 10.0;
}

DfsphParams make_dfsph_params(const Scene& s) {
  const DfsphConfig& c = s.sph.dfsph;
  const double dx = s.sph.spacing;
  const SmoothingKernel<double> k = SmoothingKernel<double>::make(c.kernel, 0.5 * c.support * dx);
  // The particle volume m / rho0 that gives a full lattice exactly the rest
  // density with this kernel and support, and the lattice's neighbour count.
  double w_sum = 0;
  int neighbours = 0;
  for_lattice_neighbours(k.support(), dx, [&](int, int, int, double r) {
    w_sum += k.W(r);
    ++neighbours;
  });
  const double volume = 1.0 / (k.W(0) + w_sum);
  // Monaghan (2005): artificial viscosity alpha is a kinematic viscosity
  // alpha h c0 / (2 (d + 2)); the solver's term carries the 2 (d + 2) = 10.
  const double nu = c.viscosity >= 0 ? c.viscosity : auto_dfsph_viscosity(s);
  DfsphParams p{};
  p.kernel = SmoothingKernel<float>::make(c.kernel, float(k.h));
  p.volume = float(volume);
  p.viscosity = float(10.0 * nu);
  p.viscosity_eta2 = float(0.01 * k.h * k.h);
  for (int face = 0; face < 6; ++face)
    if (!s.free_slip[face]) p.no_slip_faces |= 1u << face;
  p.presence_scale = float(0.5 / presence_lobe_on_lattice(k, dx, volume));
  p.speed_floor = float(expected_flow_speed(s));
  p.max_dt_viscous = nu > 0 ? float(2.0 / (nu * dfsph_viscous_rate_bound(k, dx, volume, c.wall_margin * dx)))
                            : std::numeric_limits<float>::max();
  p.sparse_neighbours = float(0.5 * neighbours);
  const double spectrum = lattice_spectrum_bound(k.support(), dx, [&](double r) { return k.dW_over_r(r); });
  p.jacobi_weight = float(std::min(0.5, DfsphParams::kJacobiTop / spectrum));
  p.tolerance = float(c.tolerance);
  p.divergence_tolerance = float(c.divergence_tolerance);
  p.min_iterations = c.min_iterations;
  p.max_iterations = c.max_iterations;
  p.max_divergence_iterations = c.max_divergence_iterations;
  p.wall_margin = float(c.wall_margin * dx);
  return p;
}

SceneSize measure_scene(const Scene& s) {
  SceneSize z;
  const double dx = s.sph.spacing;
  const double support = s.sph.grid_cell();
  z.boundary_layers = s.sph.wall_layers();
  for (const auto& b : s.fluid) {
    const Vec3d e = b.box.max - b.box.min;
    z.fluid += size_t(lattice_count(e.x, dx)) * lattice_count(e.y, dx) * lattice_count(e.z, dx);
  }
  const int L = z.boundary_layers;
  const Vec3d e = s.tank.max - s.tank.min;
  const double in_x = std::max(1.0, double(std::lround(e.x / dx))), in_y = std::max(1.0, double(std::lround(e.y / dx))),
               in_z = std::max(1.0, double(std::lround(e.z / dx)));
  const double all = (in_x + 2 * L) * (in_y + 2 * L) * (in_z + (s.open_top ? 1 : 2) * L);
  z.boundary = L > 0 ? size_t(all - in_x * in_y * in_z) : 0;
  // An obstacle's skin, mesh_layers under its surface (an estimate from
  // above: counting would mean generating it).
  z.mesh_layers = s.sph.mesh_wall_layers();
  for (const Obstacle& o : s.obstacles) z.boundary += size_t(std::ceil(1.5 * area(o.mesh) * z.mesh_layers / (dx * dx)));

  GridGeom& g = z.grid;
  g.cell_size = float(support);
  const double margin = L * dx + 0.5 * support;
  const Vec3d lo = s.tank.min - Vec3d{margin, margin, margin};
  Vec3d hi = s.tank.max + Vec3d{margin, margin, margin};
  if (s.open_top) hi.z += e.z;  // room for splashes above the rim before they count as gone
  g.origin = to_f(lo);
  const double nx = std::ceil((hi.x - lo.x) / support), ny = std::ceil((hi.y - lo.y) / support),
               nz = std::ceil((hi.z - lo.z) / support);
  const double cells = nx * ny * nz;
  z.cells = cells < 4e9 ? size_t(cells) : size_t(4e9);
  g.nx = int(std::min(nx, 2e9));
  g.ny = int(std::min(ny, 2e9));
  g.nz = int(std::min(nz, 2e9));
  // Per fluid particle: the solver's buffers (see SolverImpl: 8 x 16 bytes of
  // state, scratch and pair-loop results, 48 of presence and its scratch, 18
  // of ids, status, keys and order) plus sort scratch and the host-side copy,
  // an export's staging copies (60: position, id, velocity, presence), the
  // two pair masks (fluid and walls); the coarse + 2 slab tables and the two
  // near-cell flags.
  // PBF's step sorts by cells of one support (sph/flow_solver.inl,
  // GridGeom::halved): its slab table has 8 times the entries, and its masks
  // search the support in cells of that size.
  const bool pbf = s.sph.solver == SolverKind::Pbf;
  z.step_cells = pbf ? 8 * z.cells : z.cells;
  const double mask_span = pbf ? s.sph.pbf.support : support / dx;
  const size_t mask_bytes = 2 * (sizeof(PairWord) * pair_mask_capacity(mask_span) + sizeof(uint32_t));
  z.per_fluid = 248 + 60 + mask_bytes;
  z.bytes = z.fluid * z.per_fluid + z.boundary * 64 + z.cells * (4 + 4 * GridGeom::kSubX + 2) +
            z.step_cells * 4 * GridGeom::kSubX;
  return z;
}

ResolvedScene resolve_scene(const Scene& s) {
  return {s, make_params(s), s.sph.solver == SolverKind::Pbf ? make_pbf_params(s) : PbfParams{},
          s.sph.solver == SolverKind::Dfsph ? make_dfsph_params(s) : DfsphParams{}, measure_scene(s)};
}

std::string cpu_scale_note(const ResolvedScene& r, Backend backend) {
  const size_t n = r.size.fluid;
  if (backend != Backend::Cpu || n <= kCpuLargeScene) return "";
  // The particle count goes as spacing^-3; two significant digits, rounded up.
  const double want = r.scene.sph.spacing * std::cbrt(double(n) / double(kCpuSceneTarget));
  const double unit = std::pow(10.0, std::floor(std::log10(want)) - 1.0);
  const double spacing = std::ceil(want / unit - 1e-9) * unit;
  Scene coarse = r.scene;
  coarse.sph.spacing = spacing;
  std::ostringstream os;
  os << n << " fluid particles on the CPU backend: a GPU's work, far below real time here. --set sph.spacing="
     << spacing << " gives " << measure_scene(coarse).fluid << " (or --backend cuda on a machine with a GPU).";
  return os.str();
}

void check_fits(const ResolvedScene& r, Backend backend, bool field, const RankShare* share) {
  const Scene& s = r.scene;
  const SceneSize& z = r.size;
  const double gib = 1024.0 * 1024.0 * 1024.0;
  std::ostringstream os;
  if (z.step_cells * GridGeom::kSubX >= 0xffffffffull || z.fluid >= 0x7fffffffull || z.boundary >= 0x7fffffffull) {
    os << s.file << ": sph.spacing = " << s.sph.spacing << " gives " << z.fluid << " fluid particles, " << z.boundary
       << " wall particles and " << z.step_cells << " grid cells: more than sphray can index (2^31 particles, 2^30 cells). "
       << "Raise sph.spacing or shrink the tank.";
    throw SceneError(os.str());
  }
  // A rank: its slab's particles with the scene's walls and grid (every rank
  // holds both whole), and rank 0's frame view of the whole run besides.
  size_t bytes = z.bytes;
  if (share) {
    bytes = z.bytes - z.fluid * z.per_fluid + share->fluid * z.per_fluid + (share->whole_view ? z.bytes : 0);
    field = field && share->whole_view;
  }
  if (field) {
    const FieldSetup fs = make_field_setup(r);
    bytes += size_t(fs.geom.num_voxels()) * sizeof(float);
    if (fs.kernel != FieldKernel::Isotropic) {
      // The ellipsoids, and the sort of the pass that reads a radius around
      // each particle or voxel: keys, order, positions and its grid's slab table.
      const bool zb = fs.kernel == FieldKernel::ZhuBridson;
      const GridGeom ag = anisotropy_grid(z.grid, field_sort_radius(fs));
      if (!ag.fine_cells_indexable()) {
        const char* key = zb ? "field.zhu_bridson.radius" : "field.anisotropy.radius";
        os << s.file << ": sph.spacing = " << s.sph.spacing << " with " << key << " = "
           << (zb ? s.field.zhu_bridson.radius : s.field.anisotropy.radius) << (zb ? " voxels" : " spacings")
           << " gives the field's grid of half that reach more slabs than sphray can index (2^32). Raise "
           << "sph.spacing or " << key << ".";
        throw SceneError(os.str());
      }
      bytes += z.fluid * ((zb ? 0 : 3 * sizeof(Float4)) + 2 * sizeof(uint32_t) + sizeof(Float4)) +
               (size_t(ag.num_fine_cells()) + 1) * sizeof(uint32_t);
    }
  }
  size_t avail = 0;
  if (backend == Backend::Cuda) {
    avail = cuda_free_memory();
  } else {
    // MemAvailable counts reclaimable page cache; free pages alone would refuse
    // scenes on a machine that has merely read a lot of files.
    std::ifstream meminfo("/proc/meminfo");
    for (std::string key; meminfo >> key;) {
      size_t kib = 0;
      meminfo >> kib;
      if (key == "MemAvailable:") { avail = kib * 1024; break; }
      meminfo.ignore(64, '\n');
    }
    if (avail == 0) {
      const long pages = sysconf(_SC_AVPHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
      avail = pages > 0 && page > 0 ? size_t(pages) * size_t(page) : 0;
    }
  }
  const bool node_shared = share && backend == Backend::Cpu && share->ranks_on_node > 1;
  if (node_shared) avail /= size_t(share->ranks_on_node);
  if (avail > 0 && bytes > avail * 0.9) {
    os.precision(3);
    os << s.file << ": sph.spacing = " << s.sph.spacing << " needs about " << bytes / gib << " GiB";
    if (share)
      os << " on rank " << share->rank << " of " << share->ranks << " (" << share->fluid
         << (share->even ? " fluid particles (an even share), " : " fluid particles of its slab with its ghosts, ")
         << z.boundary << " wall particles, " << z.cells << " grid cells"
         << (share->whole_view ? ", and all " + std::to_string(z.fluid) + " particles again for the frames" : "")
         << (field ? ", the density field" : "") << "), but its ";
    else
      os << " (" << z.fluid << " fluid particles, " << z.boundary << " wall particles, " << z.cells << " grid cells"
         << (field ? ", the density field" : "") << "), but the ";
    os << backend_name(backend) << " backend has " << avail / gib << " GiB free"
       << (node_shared ? " (its share of the node's, with " + std::to_string(share->ranks_on_node) + " ranks on it)"
                       : "")
       << ". Raise sph.spacing or shrink the tank"
       << (share ? ", or run on more ranks." : ".");
    throw SceneError(os.str());
  }
}

// The field's radius as make_field_setup computes it: the solver's sums and
// the field's parameters must name the same float.
static float anisotropy_radius(const Scene& s) { return float(s.field.anisotropy.radius * s.sph.spacing); }

float pair_loop_covariance_radius(const Scene& s) {
  if (s.field.kernel != FieldKernel::Anisotropic || s.sph.solver != SolverKind::Wcsph) return 0.0f;
  const float radius = anisotropy_radius(s);
  return radius <= float(s.sph.support_radius()) ? radius : 0.0f;
}

bool field_needs_presence_step(const Scene& s, FieldKind builder, bool anisotropic) {
  return builder == FieldKind::Presence || (anisotropic && pair_loop_covariance_radius(s) > 0);
}

namespace {

// The fluid of `in` replaced by the frame's: its particles (by id), time and step.
void resume_from(SolverInput& in, const Frame& f, const Scene& s, bool moving_obstacles) {
  const size_t n = f.count();
  if (f.velocity.size() != 3 * n || f.density.size() != n)
    throw std::runtime_error("--resume: the frame has no velocity or density (export the run with "
                             "--export-fields velocity,density to resume from it)");
  if (moving_obstacles || !in.skins.empty())
    throw std::runtime_error("--resume: a scene with moving obstacles or skin waves cannot be resumed (their state "
                             "is not in the export)");
  if (f.time >= s.run.end_time - 1e-12)
    throw std::runtime_error("--resume: the frame is at t = " + std::to_string(f.time) + " s, not before run.end_time = " +
                             std::to_string(s.run.end_time) + " s");
  const size_t lattice = in.fluid_pos_rho.size();
  bool complete = n == lattice;
  for (size_t i = 0; i < n; ++i) {
    if (f.id[i] >= lattice)
      throw std::runtime_error("--resume: the frame holds particle id " + std::to_string(f.id[i]) + " but this scene has " +
                               std::to_string(lattice) + " fluid particles: it was exported from another scene or "
                               "spacing");
    complete = complete && f.id[i] == i;
  }
  if (!complete && in.kind != SolverKind::Wcsph)
    throw std::runtime_error("--resume: particles left the run before this frame; only the wcsph solver resumes such a run");
  in.fluid_pos_rho.resize(n);
  in.fluid_vel.resize(n);
  for (size_t i = 0; i < n; ++i) {
    in.fluid_pos_rho[i] = {f.position[3 * i], f.position[3 * i + 1], f.position[3 * i + 2], f.density[i]};
    in.fluid_vel[i] = {f.velocity[3 * i], f.velocity[3 * i + 1], f.velocity[3 * i + 2], 0.0f};
  }
  in.fluid_id = complete ? std::vector<uint32_t>{} : f.id;
  in.start_time = f.time;
  in.start_step = f.step;
}

}  // namespace

SolverInput make_solver_input(const ResolvedScene& r, PresenceMode presence, const Frame* resume) {
  const Scene& s = r.scene;
  const SceneSize& z = r.size;
  SolverInput in;
  in.kind = s.sph.solver;
  in.params = r.params;
  in.pbf = r.pbf;
  in.dfsph = r.dfsph;
  in.grid = z.grid;
  in.cfl = float(s.sph.cfl);
  in.min_dt = float(s.run.min_dt);
  in.max_dt = float(s.run.max_dt);
  in.presence = presence;
  in.covariance_radius = pair_loop_covariance_radius(s);
  in.covariance_mirror_walls = s.field.anisotropy.mirror_walls;
  const double dx = s.sph.spacing;
  const double rho0 = s.sph.rest_density, b_tait = in.params.tait_b, g = length(s.gravity);
  const Vec3d up = up_of(s);

  in.fluid_pos_rho.reserve(z.fluid);
  in.fluid_vel.reserve(z.fluid);
  const std::vector<ObstacleProbe> probes = obstacle_probes(s);
  in.obstacles = obstacle_meshes(s);
  in.skins = skin_inputs(s);
  for (size_t b = 0; b < s.fluid.size(); ++b) {
    const FluidBlock& blk = s.fluid[b];
    const Vec3d e = blk.box.max - blk.box.min;
    const int n[3] = {lattice_count(e.x, dx), lattice_count(e.y, dx), lattice_count(e.z, dx)};
    const Vec3d start = blk.box.min + Vec3d{(e.x - n[0] * dx) / 2 + dx / 2, (e.y - n[1] * dx) / 2 + dx / 2,
                                            (e.z - n[2] * dx) / 2 + dx / 2};
    for (int k = 0; k < n[2]; ++k)
      for (int j = 0; j < n[1]; ++j)
        for (int i = 0; i < n[0]; ++i) {
          const Vec3d p = start + Vec3d{i * dx, j * dx, k * dx};
          if (covered_before(s.fluid, b, p, dx)) continue;
          if (!probes.empty() && in_obstacle(probes, p, dx)) continue;
          // Hydrostatic start (inverse Tait): no pressure wave from a fluid released at
          // uniform density. PBF and DFSPH compute their density from the positions.
          const double depth = std::max(0.0, surface_above(s.fluid, b, p, up, dx) - dot(p, up));
          const double rho = incompressible(in.kind) ? rho0 : tait_density(b_tait, rho0, rho0 * g * depth);
          in.fluid_pos_rho.push_back({float(p.x), float(p.y), float(p.z), float(rho)});
          in.fluid_vel.push_back({float(blk.velocity.x), float(blk.velocity.y), float(blk.velocity.z), 0.0f});
        }
  }

  const int L = z.boundary_layers;  // 0 for PBF and DFSPH: their tank walls are its planes
  const AxisCoords ax = axis_coords(s.tank.min.x, s.tank.max.x, dx, L, true);
  const AxisCoords ay = axis_coords(s.tank.min.y, s.tank.max.y, dx, L, true);
  const AxisCoords az = axis_coords(s.tank.min.z, s.tank.max.z, dx, L, !s.open_top);
  const float volume = float(dx * dx * dx);
  // PBF's and DFSPH's wall particles weigh as their fluid's lattice does (the
  // volume that gives a full lattice the rest density, make_pbf_params).
  const float mesh_volume = s.sph.solver == SolverKind::Pbf     ? r.pbf.volume
                            : s.sph.solver == SolverKind::Dfsph ? r.dfsph.volume
                                                                : volume;
  in.boundary.reserve(z.boundary);
  if (L > 0) in.boundary_alpha.reserve(z.boundary);
  // A wall particle is viscous unless every face it belongs to is free-slip
  // (an edge between a free-slip and a viscous face stays viscous).
  const float wall_alpha = float(s.sph.wall_viscosity_alpha < 0 ? s.sph.viscosity_alpha : s.sph.wall_viscosity_alpha);
  auto face_of = [&](const AxisCoords& a, size_t k, int axis) { return k < a.wall_lo ? 2 * axis : 2 * axis + 1; };
  for (size_t k = 0; k < az.c.size() && L > 0; ++k)
    for (size_t j = 0; j < ay.c.size(); ++j)
      for (size_t i = 0; i < ax.c.size(); ++i) {
        const bool wx = is_wall(ax, i), wy = is_wall(ay, j), wz = is_wall(az, k);
        if (!(wx || wy || wz)) continue;
        const bool viscous = (wx && !s.free_slip[face_of(ax, i, 0)]) || (wy && !s.free_slip[face_of(ay, j, 1)]) ||
                             (wz && !s.free_slip[face_of(az, k, 2)]);
        in.boundary.push_back({float(ax.c[i]), float(ay.c[j]), float(az.c[k]), volume});
        in.boundary_alpha.push_back(viscous ? wall_alpha : 0.0f);
      }
  // Each obstacle's skin: the points of the tank's inner lattice inside the
  // mesh and within mesh_layers spacings of its surface (every solver's; PBF
  // and DFSPH: mesh_walls.h), viscous (WCSPH) like the walls
  // where it stands still; a moving one's free-slip (the pair loop's wall
  // viscosity takes walls at rest) and marked with its obstacle, whose
  // motion then carries them (their positions here: the pose at t = 0).
  bool any_moving = false;
  for (const Obstacle& o : s.obstacles) any_moving = any_moving || o.motion.moves();
  if (any_moving) in.boundary_obstacle.assign(in.boundary.size(), kStaticWall);
  for (size_t o = 0; o < probes.size(); ++o) {
    const bool moves = s.obstacles[o].motion.moves();
    const ObstacleProbe& pr = probes[o];
    const size_t before = in.boundary.size();
    const double depth = z.mesh_layers * dx;
    for (size_t k = az.wall_lo; k < az.wall_lo + az.inner; ++k) {
      if (az.c[k] < pr.box.min.z || az.c[k] > pr.box.max.z) continue;
      for (size_t j = ay.wall_lo; j < ay.wall_lo + ay.inner; ++j) {
        if (ay.c[j] < pr.box.min.y || ay.c[j] > pr.box.max.y) continue;
        for (size_t i = ax.wall_lo; i < ax.wall_lo + ax.inner; ++i) {
          if (ax.c[i] < pr.box.min.x || ax.c[i] > pr.box.max.x) continue;
          const Vec3d p{ax.c[i], ay.c[j], az.c[k]};
          if (pr.distance(p, depth) < depth && pr.inside(p)) {
            in.boundary.push_back({float(p.x), float(p.y), float(p.z), mesh_volume});
            if (L > 0) in.boundary_alpha.push_back(moves ? 0.0f : wall_alpha);  // WCSPH's wall viscosity
            if (any_moving) in.boundary_obstacle.push_back(moves ? uint8_t(o) : kStaticWall);
          }
        }
      }
    }
    if (in.boundary.size() == before) {
      std::ostringstream os;
      os << s.file << ": obstacles." << o << ".mesh: " << s.obstacles[o].path << " holds no point of the particle lattice "
         << "(sph.spacing = " << dx << " m): it is thinner than the spacing. Make it at least one spacing thick.";
      throw SceneError(os.str());
    }
  }
  if (resume) resume_from(in, *resume, s, any_moving);
  return in;
}

FieldSetup make_field_setup(const ResolvedScene& r) {
  const Scene& s = r.scene;
  const GridGeom& g = r.size.grid;
  const FieldConfig& f = s.field;
  FieldSetup out;
  VolumeGeom& v = out.geom;
  v.refine = f.refine;
  const int per = 1 << f.refine;
  v.voxel = g.cell_size / float(per);
  const double lo[3] = {s.tank.min.x, s.tank.min.y, s.tank.min.z}, hi[3] = {s.tank.max.x, s.tank.max.y, s.tank.max.z};
  const double o[3] = {g.origin.x, g.origin.y, g.origin.z};
  const int n[3] = {g.nx, g.ny, g.nz};
  int dims[3];
  for (int a = 0; a < 3; ++a) {
    int c0 = int(std::floor((lo[a] - o[a]) / g.cell_size));
    // An open top keeps the grid's room above the rim: splashes there are still liquid.
    int c1 = (a == 2 && s.open_top) ? n[a] : int(std::ceil((hi[a] - o[a]) / g.cell_size));
    c0 = std::clamp(c0, 0, n[a] - 1);
    c1 = std::clamp(c1, c0 + 1, n[a]);
    v.cell0[a] = c0;
    dims[a] = (c1 - c0) * per;
  }
  v.nx = dims[0]; v.ny = dims[1]; v.nz = dims[2];
  v.origin = {g.origin.x + v.cell0[0] * g.cell_size, g.origin.y + v.cell0[1] * g.cell_size,
              g.origin.z + v.cell0[2] * g.cell_size};
  if (double(v.nx) * v.ny * v.nz >= 4294967295.0) {
    std::ostringstream os;
    os << s.file << ": field.refine = " << f.refine << " gives a " << v.nx << " x " << v.ny << " x " << v.nz
       << " volume: more than 2^32 voxels. Lower field.refine or raise sph.spacing.";
    throw SceneError(os.str());
  }

  FieldShape& sh = out.shape;
  sh.radius = float(f.radius);
  sh.core2 = float(f.core * f.core);
  sh.offset = float(1.0 / (f.radius * f.radius + f.core * f.core));
  sh.iso = float(1.0 / (0.75 + f.core * f.core) - sh.offset);  // f(sqrt(3)/2)
  sh.coarse = sh.iso * (1.0f + 1.0f / 1024.0f);
  sh.clip = float(f.clip) * sh.iso;
  sh.min_extent = float(f.min_extent);
  sh.shrink_from = float(f.shrink_from);
  const double per_cell = std::pow(g.cell_size / s.sph.spacing, 3.0);
  out.full_fill = f.full_value_clip ? sh.clip : sh.coarse;
  out.kernel = f.kernel;
  // The tank's walls, mirrored where a kernel's setting says so.
  auto tank_walls = [&](bool mirror) { return FieldWalls{mirror, s.open_top, {to_f(s.tank.min), to_f(s.tank.max)}}; };
  AnisotropyParams& an = out.aniso;
  an.radius = anisotropy_radius(s);
  an.stretch = float(f.anisotropy.stretch);
  an.smoothing = float(f.anisotropy.smoothing);
  an.min_neighbours = uint32_t(f.anisotropy.min_neighbours);
  an.walls = tank_walls(f.anisotropy.mirror_walls);
  out.zhu_bridson.radius = float(f.zhu_bridson.radius);
  out.zhu_bridson.particle_radius = float(f.zhu_bridson.particle_radius);
  out.zhu_bridson.walls = tank_walls(f.zhu_bridson.mirror_walls);
  // With ellipsoids a particle's own voxel need not be inside (a flat kernel
  // is thinner than a voxel): only full cells are filled, and each particle's
  // voxel is marked only where its own kernel reaches the iso value there.
  out.mark_occupied = f.refine > 0 || f.kernel == FieldKernel::Anisotropic;
  out.full_count = uint32_t(std::max(1.0, std::ceil(f.full_fraction * per_cell - 1e-9)));
  // Liquid beyond every face of a full cell: a quarter of a cell at rest,
  // whose surface then lies at least a voxel (at refine 2) beyond the face.
  out.face_count = uint32_t(std::max(1.0, std::ceil(0.25 * per_cell - 1e-9)));
  return out;
}

}  // namespace sphray
