// ParticleTransport over NCCL (dist/transport.h).
#include <cuda_runtime.h>
#include <nccl.h>

#include <cstring>
#include <stdexcept>
#include <string>

#include "transport.h"

namespace sphray {

namespace {

void check(ncclResult_t rc, const char* what) {
  if (rc != ncclSuccess) throw std::runtime_error(std::string("NCCL: ") + what + " failed: " + ncclGetErrorString(rc));
}
void check(cudaError_t rc, const char* what) {
  if (rc != cudaSuccess) throw std::runtime_error(std::string("CUDA: ") + what + " failed: " + cudaGetErrorString(rc));
}

// The records go over NCCL, GPU to GPU, on the stream the caller names: the
// legacy default stream, where the solver's kernels run, or a stream beside
// it (PBF's ghost refresh, overlapped with a pass's interior work). The step's two extremes and the
// per-peer counts go through the host over MPI: the host waits for both
// anyway (it sizes the receive buffers, and reads the step's outcome), and
// on the device machine (2 H200, NVLink) an NCCL all-reduce of two floats
// took 2.3-2.8 ms per step against 0.1 ms for the copy and MPI_Allreduce
// (docs/benchmarks.md, "Scale-out").
class NcclTransport final : public ParticleTransport {
 public:
  explicit NcclTransport(Comm& comm) : rank_(comm.rank()), mpi_(make_mpi_transport(comm)) {
    ncclUniqueId id{};
    if (rank_ == 0) check(ncclGetUniqueId(&id), "ncclGetUniqueId");
    std::string bytes(reinterpret_cast<const char*>(&id), sizeof(id));
    comm.broadcast(bytes, 0);
    std::memcpy(&id, bytes.data(), sizeof(id));
    check(ncclCommInitRank(&comm_, comm.size(), id, rank_), "ncclCommInitRank");
  }
  ~NcclTransport() override { ncclCommDestroy(comm_); }
  void max(float* v, int n) override {
    through_host(v, n, [&](float* h) { mpi_->max(h, n); });
  }
  void sum(double* v, int n) override {
    through_host(v, n, [&](double* h) { mpi_->sum(h, n); });
  }
  void exchange_counts(const SlabBounds& b, const PeerCounts& send, PeerCounts& recv) override {
    mpi_->exchange_counts(b, send, recv);
  }
  void exchange_records(const SlabBounds& b, size_t record_bytes, const void* const send[kPeers],
                        const uint32_t send_count[kPeers], void* const recv[kPeers],
                        const uint32_t recv_count[kPeers], void* stream) override {
    const cudaStream_t on = stream ? static_cast<cudaStream_t>(stream) : cudaStreamLegacy;
    check(ncclGroupStart(), "ncclGroupStart");
    for (int k = 0; k < kPeers; ++k) {
      if (k == kSelf || !b.exists[k]) continue;
      const int peer = rank_ + k - kSelf;
      if (send_count[k] > 0)
        check(ncclSend(send[k], send_count[k] * record_bytes, ncclChar, peer, comm_, on),
              "ncclSend");
      if (recv_count[k] > 0)
        check(ncclRecv(recv[k], recv_count[k] * record_bytes, ncclChar, peer, comm_, on),
              "ncclRecv");
    }
    check(ncclGroupEnd(), "ncclGroupEnd");
  }

 private:
  // A few values (device or host memory) reduced by `reduce` on a host copy.
  template <class T, class Reduce>
  static void through_host(T* v, int n, Reduce reduce) {
    T h[8];
    if (n > 8) throw std::logic_error("NcclTransport: at most 8 values per reduction");
    check(cudaMemcpy(h, v, sizeof(T) * size_t(n), cudaMemcpyDefault), "cudaMemcpy");
    reduce(h);
    check(cudaMemcpy(v, h, sizeof(T) * size_t(n), cudaMemcpyDefault), "cudaMemcpy");
  }

  int rank_;
  std::unique_ptr<ParticleTransport> mpi_;  // the counts and the extremes
  ncclComm_t comm_{};
};

}  // namespace

std::unique_ptr<ParticleTransport> make_nccl_transport(Comm& comm) { return std::make_unique<NcclTransport>(comm); }

}  // namespace sphray
