// The ranks of a decomposed run and what they exchange (dist/slab_solver.h):
// MPI processes (`mpirun -np R sphray run ...`), or the one process of an
// ordinary run. Collective calls: every rank makes the same calls in the same
// order.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace sphray {

class Comm {
 public:
  virtual ~Comm() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  // In place over all ranks: element-wise sum, minimum.
  virtual void sum(double* v, int n) = 0;
  virtual void min(int* v, int n) = 0;
  // Rank 0 receives every rank's bytes (its own included), by rank; the
  // others receive nothing.
  virtual std::vector<std::vector<char>> gather(const std::vector<char>& mine) = 0;
  // Every rank sends rank r the next send[r] bytes of `out` (rank 0's
  // first), and receives what each sent it, concatenated by rank (its own
  // included); recv[r]: the bytes from rank r.
  virtual std::vector<char> all_to_all(const std::vector<char>& out, const std::vector<int>& send,
                                       std::vector<int>& recv) = 0;
  // Every rank receives `root`'s string.
  virtual void broadcast(std::string& s, int root) = 0;
};

// The one rank of an ordinary run.
std::unique_ptr<Comm> make_single_comm();

// Whether this build has MPI, and whether this process was started by an MPI
// launcher (mpirun, srun): its environment says so. An ordinary start never
// initialises MPI, so a one-process run is today's run.
bool mpi_built();
bool started_by_mpi_launcher();
// The number of processes the launcher started (0 without one).
int launcher_size();

// MPI over MPI_COMM_WORLD: initialises MPI (once; finalised at exit). Throws
// std::runtime_error in a build without MPI.
std::unique_ptr<Comm> make_mpi_comm();

// Where MPI runs this process among several: its rank (0 otherwise), and an
// end for an error that only this rank may have met: MPI_Abort ends every
// rank with `code` (a rank that returned instead would leave the others
// waiting in their next exchange). Without several ranks, returns.
int world_rank();
bool several_ranks();
void abort_ranks(int code);

// The rank of this process among those on its node, and their number (from
// the launcher's environment; 0 and 1 without one): one GPU per rank.
int local_rank();
int local_size();

}  // namespace sphray
