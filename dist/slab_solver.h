// A simulation over several ranks (MPI processes), one slab of the domain
// each (slabs.h): each rank steps the particles it owns with the solver of
// an ordinary run, among copies ("ghosts") of its neighbours' particles
// within one support radius of its slab, two near wall particles. Per step,
// inside the solver (sph/exchange.h, Solver::set_slab), on its backend:
//   1. the step's extremes are reduced over the ranks before its size is
//      chosen, so every rank takes the same dt;
//   2. after the particles move, one exchange: every particle that left the
//      slab goes to its new owner, and copies of the owned particles within
//      the halo of a neighbouring slab go there as ghosts (the ghosts of the
//      last step are dropped); then the grid is built as in any step.
// The transport is MPI on the CPU backend and NCCL on CUDA (dist/transport.h).
// Every `rebalance_every` steps the cuts move toward the quantiles of the
// particles when the ranks' counts differ by more than `rebalance_above`.
// Why those widths: WCSPH's step reads its neighbours' state (position,
// density, predicted velocity, p / rho^2: all from the start of the step) and
// the wall particles' pressure, which each wall particle sums from the fluid
// within one support of it: near walls an owned particle's step depends on
// fluid up to two supports away. Ghosts' own results (incomplete sums at the
// halo's edge) are discarded: they are never moved nor counted (kStatusGhost).
// PBF and DFSPH (plan_slabs): one support of their own kernel everywhere, the
// exchange where their neighbour masks are found (PBF: at x* after the
// prediction), and the ghosts' values refreshed from their owners after
// every pass of their iterations (docs/design.md, "Scale-out").
// Outputs: at each output frame the ranks gather their owned particles on
// rank 0 (gather_frame), which writes every output, or where the export is
// the only output and every rank writes its rows of it (rank_export.h), each
// keeps its own; with frame_view, rank 0 also sorts them into a grid of its
// own for the field and the renderers.
#pragma once

#include <functional>
#include <memory>

#include "comm.h"
#include "slabs.h"
#include "sph/solver.h"

namespace sphray {

// A step that failed on some rank, raised on every rank alike (the ranks
// agree on it before raising: none is left waiting).
struct RanksStopped : SimulationError {
  using SimulationError::SimulationError;
};

struct SlabOptions {
  int rebalance_every = 100;     // steps between balance checks (0: never)
  double rebalance_above = 0.1;  // move the cuts when max / mean count - 1 exceeds this
  // Rank 0 sorts the particles it gathers at an output frame into a grid of
  // its own, for view(): the density field and the renderers read them there
  // (on its backend, as `sphray render --from` reads an export's frame).
  bool frame_view = false;
  // Rank 0 receives every rank's particles at an output frame (download(),
  // flow_sums(), download_raw() read them there); false where no output
  // reads them on rank 0 (an export written by every rank, which reads
  // download_owned() on each).
  bool gather_to_root = true;
  // Every rank keeps its own particles at an output frame, for
  // download_owned() (the export written by every rank, rank_export.h).
  bool keep_owned = false;
  // SlabBounds::overlap_above (PBF's ghost refresh beside its passes).
  float overlap_above = SlabBounds::kOverlapAuto;
};

using SolverMaker = std::function<std::unique_ptr<Solver>(const SolverInput&)>;

// The plan of `in`'s run over `ranks` ranks: least slab width and halo near
// walls two support radii (one elsewhere), cuts at the quantiles of the
// initial particles along `axis` (0 x, 1 y, 2 z), or with -1 along the axis
// whose busiest rank holds the fewest of them with its ghosts (slabs.h).
// Throws std::invalid_argument when the domain cannot hold that many slabs
// along that axis, or along any (check_rank_count).
SlabPlan plan_slabs(const SolverInput& in, int ranks, int axis = -1);

// The fluid particles of `in` that rank `rank` holds at the start: its own and
// its ghosts, counted within the wider halo (plan.halo) on both sides, an
// upper bound for its memory (pipeline/setup.h, RankShare).
size_t held_particles(const SolverInput& in, const SlabPlan& plan, int rank);

// This rank's solver of a decomposed run cut as `plan` (plan_slabs, one slab
// per rank): `in` holds the whole run's particles (every rank resolves the
// same scene); the rank keeps its own. Collective: every rank calls it. Every
// solver (PBF and DFSPH refresh their ghosts within the step: GhostRefresh,
// sph/exchange_impl.inl). The transport follows the backend: MPI for the CPU,
// NCCL for CUDA.
std::unique_ptr<Solver> make_slab_solver(SolverInput in, const SlabPlan& plan, Comm& comm, Backend backend,
                                         const SolverMaker& make, const SlabOptions& opt = {});

}  // namespace sphray
