// What the commands that run over several ranks (`run`, `view`) share: the
// ranks of this process, and each rank's GPU.
#pragma once

#include <memory>

#include "dist/comm.h"
#include "sph/solver.h"

namespace sphray::cli {

// The ranks of this run: MPI's when an MPI launcher started it, else one.
std::unique_ptr<Comm> run_ranks();

// The CUDA device of this rank: one per rank on each node (fewer devices
// than ranks on a node is an error, not a hang).
void pick_rank_device(Backend b);

}  // namespace sphray::cli
