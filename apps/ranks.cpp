#include "ranks.h"

#include <stdexcept>
#include <string>

#include "core/device.h"

namespace sphray::cli {

std::unique_ptr<Comm> run_ranks() {
  if (!started_by_mpi_launcher()) return make_single_comm();
  if (!mpi_built())
    throw std::runtime_error("started by an MPI launcher, but this sphray was built without MPI: each process would "
                             "run the whole scene (install libopenmpi-dev and rebuild; tools/setup.sh does)");
  return make_mpi_comm();
}

void pick_rank_device(Backend b) {
  if (b != Backend::Cuda) return;
  const int have = cuda_device_count(), ranks_here = local_size();
  if (ranks_here > have)
    throw std::runtime_error(std::to_string(ranks_here) + " ranks on this node but " + std::to_string(have) +
                             " CUDA device(s): a run over several ranks takes one GPU per rank (start fewer ranks "
                             "per node, or use --backend cpu)");
  use_cuda_device(local_rank());
}

}  // namespace sphray::cli
