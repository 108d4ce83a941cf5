#include "comm.h"
#include "transport.h"

#include <cstdlib>
#include <stdexcept>

namespace sphray {

namespace {

class SingleComm final : public Comm {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  void sum(double*, int) override {}
  void min(int*, int) override {}
  std::vector<std::vector<char>> gather(const std::vector<char>& mine) override { return {mine}; }
  std::vector<char> all_to_all(const std::vector<char>& out, const std::vector<int>& send,
                               std::vector<int>& recv) override {
    recv = send;
    return out;
  }
  void broadcast(std::string&, int) override {}
};

int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::atoi(v) : fallback;
}

}  // namespace

std::unique_ptr<Comm> make_single_comm() { return std::make_unique<SingleComm>(); }

// Open MPI's mpirun sets OMPI_COMM_WORLD_SIZE; PMI launchers (MPICH's Hydra,
// srun) PMI_SIZE. Not SLURM_NTASKS: a batch script has it without a launcher.
int launcher_size() { return env_int("OMPI_COMM_WORLD_SIZE", env_int("PMI_SIZE", 0)); }

bool started_by_mpi_launcher() { return launcher_size() > 0; }

int local_rank() {
  return env_int("OMPI_COMM_WORLD_LOCAL_RANK", env_int("MPI_LOCALRANKID", env_int("SLURM_LOCALID", 0)));
}

int local_size() {
  return env_int("OMPI_COMM_WORLD_LOCAL_SIZE", env_int("MPI_LOCALNRANKS", env_int("SLURM_NTASKS_PER_NODE", 1)));
}

#if !defined(SPHRAY_HAVE_MPI)
std::unique_ptr<ParticleTransport> make_mpi_transport(Comm&) {
  make_mpi_comm();  // throws: no MPI in this build
  return nullptr;
}
bool mpi_built() { return false; }
int world_rank() { return 0; }
bool several_ranks() { return false; }
void abort_ranks(int) {}
std::unique_ptr<Comm> make_mpi_comm() {
  throw std::runtime_error("this sphray was built without MPI (configure with -DSPHRAY_MPI=ON and an MPI installed: "
                           "Debian/Ubuntu libopenmpi-dev)");
}
#endif

#if !defined(SPHRAY_HAVE_NCCL)
std::unique_ptr<ParticleTransport> make_nccl_transport(Comm&) {
  throw std::runtime_error("this sphray was built without NCCL (it comes with the CUDA toolkit or libnccl-dev): a run "
                           "over several ranks on CUDA needs it; use --backend cpu");
}
#endif

}  // namespace sphray
