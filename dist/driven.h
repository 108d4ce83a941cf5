// A run over several ranks that rank 0 drives call by call (`sphray view`
// under mpirun: the viewer's loop decides, frame by frame, how far to step,
// from the wall clock and the user's keys, which only rank 0 sees). Rank 0's
// solver (drive_from_root) tells the other ranks each collective call it is
// about to make (a step to `until`, a frame's gather, the presence mode);
// the other ranks (serve_root) make the same calls on their own solvers, in
// the same order, until rank 0 says the run ends.
#pragma once

#include <functional>
#include <memory>

#include "comm.h"
#include "sph/solver.h"

namespace sphray {

// Rank 0: `slab` (a decomposed run's solver, make_slab_solver) wrapped so
// that every collective call goes to the other ranks first.
std::unique_ptr<Solver> drive_from_root(std::unique_ptr<Solver> slab, Comm& comm);

// Rank 0: the other ranks drop their solver and make a new one (rank 0
// makes its own after this, collectively: make_slab_solver).
void tell_new_solver(Comm& comm);

// Rank 0: the run ends; the other ranks return from serve_root.
void tell_quit(Comm& comm);

// The other ranks: `make` a solver (collectively, as rank 0 makes its
// first), then follow rank 0's calls until it quits. A step that failed on
// every rank alike (RanksStopped) leaves the run waiting for rank 0, as the
// viewer pauses.
void serve_root(Comm& comm, const std::function<std::unique_ptr<Solver>()>& make);

}  // namespace sphray
