// ParticleTransport over NCCL: the exchange's records and the step's
// reduction go GPU to GPU on the stream the solver's kernels run on (the
// legacy default stream); only the per-peer counts pass through the host.
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

class NcclTransport final : public ParticleTransport {
 public:
  explicit NcclTransport(Comm& comm) : rank_(comm.rank()) {
    ncclUniqueId id{};
    if (rank_ == 0) check(ncclGetUniqueId(&id), "ncclGetUniqueId");
    std::string bytes(reinterpret_cast<const char*>(&id), sizeof(id));
    comm.broadcast(bytes, 0);
    std::memcpy(&id, bytes.data(), sizeof(id));
    check(ncclCommInitRank(&comm_, comm.size(), id, rank_), "ncclCommInitRank");
    check(cudaMalloc(&counts_, 4 * kPeers * sizeof(uint32_t)), "cudaMalloc");
  }
  ~NcclTransport() override {
    cudaFree(counts_);
    ncclCommDestroy(comm_);
  }
  void max(float* v, int n) override {
    check(ncclAllReduce(v, v, size_t(n), ncclFloat, ncclMax, comm_, stream()), "ncclAllReduce");
  }
  void exchange_counts(const SlabBounds& b, const PeerCounts& send, PeerCounts& recv) override {
    uint32_t host[2 * kPeers][2] = {};
    for (int k = 0; k < kPeers; ++k) {
      host[k][0] = send.total[k];
      host[k][1] = send.owned[k];
    }
    uint32_t* out = counts_;
    uint32_t* in = counts_ + 2 * kPeers;
    check(cudaMemcpyAsync(out, host, 2 * kPeers * sizeof(uint32_t), cudaMemcpyHostToDevice, stream()), "cudaMemcpyAsync");
    check(ncclGroupStart(), "ncclGroupStart");
    for (int k = 0; k < kPeers; ++k) {
      if (k == kSelf || !b.exists[k]) continue;
      check(ncclSend(out + 2 * k, 2, ncclUint32, rank_ + k - kSelf, comm_, stream()), "ncclSend");
      check(ncclRecv(in + 2 * k, 2, ncclUint32, rank_ + k - kSelf, comm_, stream()), "ncclRecv");
    }
    check(ncclGroupEnd(), "ncclGroupEnd");
    check(cudaMemcpyAsync(host[kPeers], in, 2 * kPeers * sizeof(uint32_t), cudaMemcpyDeviceToHost, stream()),
          "cudaMemcpyAsync");
    check(cudaStreamSynchronize(stream()), "cudaStreamSynchronize");
    for (int k = 0; k < kPeers; ++k) {
      const bool peer = k != kSelf && b.exists[k];
      recv.total[k] = peer ? host[kPeers + k][0] : 0;
      recv.owned[k] = peer ? host[kPeers + k][1] : 0;
    }
  }
  void exchange(const SlabBounds& b, ExchangeRecord* const send[kPeers], const uint32_t send_count[kPeers],
                ExchangeRecord* const recv[kPeers], const uint32_t recv_count[kPeers]) override {
    check(ncclGroupStart(), "ncclGroupStart");
    for (int k = 0; k < kPeers; ++k) {
      if (k == kSelf || !b.exists[k]) continue;
      const int peer = rank_ + k - kSelf;
      if (send_count[k] > 0)
        check(ncclSend(send[k], send_count[k] * sizeof(ExchangeRecord), ncclChar, peer, comm_, stream()), "ncclSend");
      if (recv_count[k] > 0)
        check(ncclRecv(recv[k], recv_count[k] * sizeof(ExchangeRecord), ncclChar, peer, comm_, stream()), "ncclRecv");
    }
    check(ncclGroupEnd(), "ncclGroupEnd");
  }

 private:
  static cudaStream_t stream() { return cudaStreamLegacy; }
  int rank_;
  ncclComm_t comm_{};
  uint32_t* counts_ = nullptr;  // device: 2 x kPeers sent, 2 x kPeers received
};

}  // namespace

bool nccl_built() { return true; }
std::unique_ptr<ParticleTransport> make_nccl_transport(Comm& comm) { return std::make_unique<NcclTransport>(comm); }

}  // namespace sphray
