// The transports of a decomposed run's per-step traffic (sph/exchange.h):
// MPI point-to-point on the CPU backend (host memory); on CUDA the particles
// go GPU to GPU over NCCL (its communicator set up from an MPI-broadcast id),
// the step's extremes and the per-peer counts over MPI through the host.
#pragma once

#include <memory>

#include "comm.h"
#include "sph/exchange.h"

namespace sphray {

// Over MPI_COMM_WORLD (make_mpi_comm first). Throws in a build without MPI.
std::unique_ptr<ParticleTransport> make_mpi_transport(Comm& comm);
// Over NCCL among comm's ranks, on the current CUDA device (use_cuda_device
// first). Throws in a build without NCCL (or CUDA).
std::unique_ptr<ParticleTransport> make_nccl_transport(Comm& comm);

}  // namespace sphray
