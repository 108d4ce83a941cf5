// The SPH solver as the host sees it: one interface, two backends built from
// one source (sph/solver_impl.inl). The pipeline and the tests only talk
// to this interface.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/device.h"
#include "core/host_memory.h"
#include "nsearch/grid.h"
#include "integrate.h"  // StepLimits
#include "obstacles.h"
#include "params.h"
#include "dfsph_params.h"
#include "exchange.h"
#include "pbf_params.h"
#include "skin_params.h"
#include "solver_kind.h"

namespace sphray {

// When the pair loop also computes particle presence: never, every step, or
// only on a step that may reach the time its step() call was given (the last
// one or two steps before an output frame, whose field builder reads it).
enum class PresenceMode { Off, EveryStep, AtUntil };

// A run that cannot go on (non-finite value, time step below its floor).
// In a run over several ranks a rank may stop for a particle another rank
// holds (the largest speed is reduced over all ranks): `elsewhere` then says
// so, and the rank that holds it reports (dist/slab_solver.cpp).
struct SimulationError : std::runtime_error {
  using std::runtime_error::runtime_error;
  SimulationError(const std::string& what, bool elsewhere) : std::runtime_error(what), elsewhere(elsewhere) {}
  bool elsewhere = false;
};

struct SolverInput {
  SolverKind kind = SolverKind::Wcsph;
  SphParams params;
  PbfParams pbf{};      // kind == Pbf
  DfsphParams dfsph{};  // kind == Dfsph
  GridGeom grid;
  std::vector<Float4> fluid_pos_rho;  // x, y, z, initial density
  std::vector<Float4> fluid_vel;      // vx, vy, vz, - (the solver keeps p / rho^2 in w)
  // x, y, z, volume: WCSPH's tank walls and every solver's obstacle skins
  // (PBF's and DFSPH's tank walls are its planes, mirror_walls.h).
  std::vector<Float4> boundary;
  std::vector<float> boundary_alpha;  // WCSPH's wall viscosity per boundary particle (0 = free slip); PBF, DFSPH: empty
  // Per boundary particle: the moving obstacle it belongs to (its index in
  // `obstacles`), or kStaticWall. Empty: all static. A moving one's position
  // above is its pose at t = 0; the solver moves it with the obstacle.
  std::vector<uint8_t> boundary_obstacle;
  // Triangle meshes the particles' paths stop at (obstacles.h), at most
  // kMaxObstacles; the wall particles inside them are in `boundary`.
  std::vector<MeshInput> obstacles;
  // Obstacles whose skins carry waves (sph/skin.h); the solver is then
  // wrapped (with_skins) so that its steps also advance them.
  std::vector<SkinInput> skins;
  // Step control, from the scene (sph.cfl, run.min_dt, run.max_dt; their
  // defaults are the scene's): WCSPH's CFL on h and the sound speed, PBF's
  // and DFSPH's on the spacing and the largest particle speed.
  float cfl = 0;
  float min_dt = 0;  // a step below this is an error
  float max_dt = 0;
  PresenceMode presence = PresenceMode::Off;  // only when a later stage needs it
  // [m] The anisotropic field's neighbourhood radius (field/anisotropy.h)
  // when the solver's neighbour loop sums its covariance on the steps that
  // compute presence (ParticleView::covariance); 0: it does not. WCSPH
  // only, and only within its support (make_solver_input). With
  // covariance_mirror_walls the sums take the images of the particles across
  // the tank's walls within that radius (field.anisotropy.mirror_walls).
  float covariance_radius = 0;
  bool covariance_mirror_walls = false;
  // Words per particle kept in each pair mask (nsearch/pair_masks.h); -1:
  // pair_mask_capacity of the support. A particle needing more is served by
  // the direct loop (the tests use 0 and 1 to check that path).
  int pair_mask_words = -1;
  // A decomposed run (dist/slab_solver.h): each fluid particle's index in the
  // whole run's initial list (empty: 0, 1, ..., n - 1), and the transport
  // over the ranks (sph/exchange.h; it outlives the solver): the step's
  // extremes are reduced over the ranks before its size is chosen, so that
  // every rank takes the same dt, and each step exchanges particles with
  // the other ranks (Solver::set_slab). WCSPH and PBF.
  std::vector<uint32_t> fluid_id;
  ParticleTransport* transport = nullptr;
  // A resumed run (--resume): the time and step count of the state above.
  double start_time = 0;
  uint64_t start_step = 0;
};

// Host copy of the fluid state, in the solver's current (sorted) order.
struct HostParticles {
  std::vector<uint32_t> id;  // index in the initial particle list
  std::vector<Vec3f> pos, vel;
  std::vector<float> density;
  std::vector<std::array<float, 6>> presence;  // empty when presence is off
  std::vector<uint8_t> status;  // a decomposed run's (integrate.h, kStatusGhost: another rank's particle); else empty
};

// The solver's current fluid state where its backend keeps it (device pointers
// on CUDA), for later stages that run on the same backend (the field builder).
// Valid until the next step. Particles are sorted by cell and `offsets` matches
// their positions exactly (the grid is rebuilt at the end of every step).
struct ParticleView {
  Backend backend{};
  uint32_t n = 0;
  const Float4* pos = nullptr;        // x, y, z, density
  const uint32_t* offsets = nullptr;  // grid.num_cells() + 1
  const float* presence = nullptr;    // [6][n] (+x,-x,+y,-y,+z,-z); null unless the last step computed it
  GridGeom grid{};
  const uint32_t* fine_offsets = nullptr;  // the x-slab table (nsearch/grid.h): neighbour queries (field/anisotropy.h)
  // The anisotropic kernels' neighbour sums within covariance_radius [m]
  // (sph/covariance.h, [3][n]), where the last step's neighbour loop summed
  // them (SolverInput::covariance_radius); null otherwise.
  const Float4* covariance = nullptr;
  float covariance_radius = 0;
  bool covariance_mirror_walls = false;  // the sums hold the images across the tank's walls
};

// Device buffers copied as they are (sorted order, no conversion), for sinks
// that convert on another thread (the HDF5 export).
// Pinned where the backend provides it (host_memory.h).
struct RawParticles {
  PinnedVector<Float4> pos;      // x, y, z, density
  PinnedVector<Float4> vel;      // vx, vy, vz, - (empty unless asked for)
  PinnedVector<uint32_t> id;
  PinnedVector<float> presence;  // [6][n] (empty unless asked for and computed)
  // Call before reading: the copies may still be running (CUDA). Empty: done.
  std::function<void()> ready;
};

// Milliseconds of the last step. pairs: the wall pressure and the one
// neighbour loop of forces, density rate and presence (interaction.h);
// integrate: the step-size reduction and the kick/density/drift; grid: the
// sort, the cell tables and the next step's pair masks.
// The last step's constraint or pressure solve (PBF, DFSPH; WCSPH has none
// and reports zeros): iterations run (DFSPH: of the pressure solve, and of
// its divergence solve) and the density error of the state after the step,
// as compression max(rho / rho0 - 1, 0) averaged over the particles and at
// its largest; converged: the tolerances were met within the iteration
// limits (always true without a tolerance).
struct SolveStats {
  int iterations = 0;
  int divergence_iterations = 0;
  double density_error_mean = 0, density_error_max = 0;
  bool converged = true;
};

// What a metrics row reduces over the fluid particles (pipeline/sinks.h):
// their largest x and the sum of their squared speeds (a decomposed run's
// ghosts left out). max_x is -1e300 without particles.
struct FlowSums {
  double max_x = -1e300;
  double speed2_sum = 0;
};
// FlowSums of particles on the host (status, where given, marks the ghosts).
FlowSums flow_sums_of(const HostParticles& p);

struct StageTimes {
  double grid = 0, pairs = 0, integrate = 0;
  double skin = 0;  // the obstacles' skin waves (sph/skin.h), when the scene has any
  double exchange = 0;  // a decomposed run's exchange of particles with the other ranks (sph/exchange.h)
  double total() const { return grid + pairs + integrate + skin + exchange; }
};

class SkinSet;

class Solver {
 public:
  virtual ~Solver() = default;
  virtual Backend backend() const = 0;
  virtual SolverKind kind() const = 0;
  // Advances one adaptive step, never past `until` [s]. Throws SimulationError.
  virtual void step(double until) = 0;
  virtual double time() const = 0;
  virtual uint64_t steps() const = 0;
  virtual size_t num_fluid() const = 0;       // particles still in the run
  virtual size_t num_removed() const = 0;     // left the grid (open top) and dropped
  virtual uint64_t num_clamped() const = 0;   // particle-steps put back on a wall face
  virtual const StepLimits& last_limits() const = 0;
  virtual const StageTimes& last_stage_times() const = 0;
  virtual SolveStats last_solve() const { return {}; }
  // Presence is computed by the steps that follow as the mode says (its
  // buffers are allocated on the first mode other than Off); has_presence()
  // says whether the last step computed it.
  virtual void set_presence(PresenceMode mode) = 0;
  virtual PresenceMode presence_mode() const = 0;
  virtual bool has_presence() const = 0;
  virtual ParticleView view() const = 0;
  virtual size_t device_bytes() const = 0;    // buffers this solver holds
  virtual HostParticles download() const = 0;
  // FlowSums of the current state, reduced where the particles are (the
  // solvers on their backend: no download); this default reduces download().
  virtual FlowSums flow_sums() const;
  virtual void download_raw(RawParticles& out, bool velocity, bool presence) const = 0;
  // This rank's own particles at the last output frame, as download_raw
  // gives them (no presence): a decomposed run's without its ghosts and
  // without gathering them on rank 0 (its export written by every rank,
  // dist/rank_export.h); every particle otherwise.
  virtual void download_owned(RawParticles& out, bool velocity) const { download_raw(out, velocity, false); }
  virtual std::vector<Vec3f> boundary_positions() const = 0;  // the wall particles, where they are now
  // Per particle in the order of download(), the pressure [Pa] of the last
  // step's solves (DFSPH: the pressure and the divergence solve's, which
  // both act over the step); empty for a solver without one (WCSPH's
  // pressure follows from the density, tait_pressure). A solve that stops at
  // a tolerance leaves the pressure of one step noisy: average over steps.
  // Zero before the first step.
  virtual std::vector<float> pressures() const { return {}; }
  // The same pressure [Pa] per particle in view()'s order, computed on the
  // solver's backend into a buffer it keeps (valid until the next step);
  // null for a solver without one (PBF). WCSPH: tait_pressure of the density.
  virtual const float* device_pressure() { return nullptr; }
  // A decomposed run: this rank's slab and its neighbours' (sph/exchange.h).
  // Exchanges particles with the other ranks at once (collective), and so
  // does every later step (WCSPH after it moves them, PBF after its
  // prediction): the particles that left the slab go to their owners, and
  // copies of those within the halo of a neighbouring slab go there as
  // ghosts (integrate.h, kStatusGhost: read by the neighbour loops, never
  // moved by the step, counted, or returned by num_fluid()).
  // Solvers other than WCSPH and PBF throw std::logic_error.
  virtual void set_slab(const SlabBounds&) { throw std::logic_error("this solver cannot run over several ranks"); }
  // A decomposed run: this rank's own particles (not its ghosts) per bin of
  // `bin` metres along `axis` from `lo`, the first and last of `bins` bins
  // holding those beyond (dist/slabs.h, AxisHistogram). On the solver's
  // backend where it can; by default from download().
  virtual std::vector<double> axis_counts(int axis, double lo, double bin, size_t bins) const;
  // Called by the run loop at every output frame before the sinks read the
  // solver (a decomposed run gathers its ranks' particles then).
  virtual void gather_frame() {}
  // The skins of the run's obstacles (sph/skin.h), or null.
  virtual SkinSet* skins() { return nullptr; }
  virtual const SkinSet* skins() const { return nullptr; }
};

std::unique_ptr<Solver> make_cpu_solver(const SolverInput& in);
std::unique_ptr<Solver> make_cuda_solver(const SolverInput& in);  // throws if CUDA is unavailable


}  // namespace sphray
