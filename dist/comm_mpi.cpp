// Comm over MPI_COMM_WORLD. Errors return (MPI_ERRORS_RETURN) and become
// exceptions; a rank that dies is reported by the launcher, which ends the
// others (docs/design.md, "Scale-out").
#include <mpi.h>

#include <cstdlib>
#include <utility>
#include <stdexcept>
#include <string>

#include "comm.h"
#include "transport.h"

namespace sphray {

namespace {

void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(rc, text, &len);
  throw std::runtime_error(std::string("MPI: ") + what + " failed: " + std::string(text, size_t(len)));
}

// Displacements of MPI's "v" calls from their byte counts (int: 2 GiB in all).
std::vector<int> displacements(const std::vector<int>& counts) {
  std::vector<int> d(counts.size(), 0);
  long long at = 0;
  for (size_t r = 0; r < counts.size(); ++r) {
    if (at > INT32_MAX) throw std::runtime_error("MPI: an exchange over 2 GiB");
    d[r] = int(at);
    at += counts[r];
  }
  return d;
}

class MpiComm final : public Comm {
 public:
  MpiComm() {
    int ready = 0;
    MPI_Initialized(&ready);
    if (!ready) {
      check(MPI_Init(nullptr, nullptr), "MPI_Init");
      std::atexit([] {
        int done = 0;
        MPI_Finalized(&done);
        if (!done) MPI_Finalize();
      });
    }
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  void sum(double* v, int n) override {
    check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD), "MPI_Allreduce");
  }
  void min(int* v, int n) override {
    check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_INT, MPI_MIN, MPI_COMM_WORLD), "MPI_Allreduce");
  }
  std::vector<std::vector<char>> gather(const std::vector<char>& mine) override {
    if (mine.size() > size_t(INT32_MAX)) throw std::runtime_error("MPI: a message over 2 GiB");
    int count = int(mine.size());
    std::vector<int> counts(size_t(size_), 0);
    check(MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD), "MPI_Gather");
    std::vector<int> disp(size_t(size_), 0);
    if (rank_ == 0) disp = displacements(counts);
    std::vector<char> flat(rank_ == 0 ? size_t(disp.back()) + size_t(counts.back()) : 0);
    check(MPI_Gatherv(mine.data(), count, MPI_BYTE, flat.data(), counts.data(), disp.data(), MPI_BYTE, 0,
                      MPI_COMM_WORLD),
          "MPI_Gatherv");
    std::vector<std::vector<char>> out;
    if (rank_ != 0) return out;
    out.resize(size_t(size_));
    for (int r = 0; r < size_; ++r) out[size_t(r)].assign(flat.begin() + disp[r], flat.begin() + disp[r] + counts[r]);
    return out;
  }
  std::vector<char> all_to_all(const std::vector<char>& out, const std::vector<int>& send,
                               std::vector<int>& recv) override {
    if (int(send.size()) != size_) throw std::logic_error("all_to_all: one count per rank");
    recv.assign(send.size(), 0);
    check(MPI_Alltoall(send.data(), 1, MPI_INT, recv.data(), 1, MPI_INT, MPI_COMM_WORLD), "MPI_Alltoall");
    const std::vector<int> send_at = displacements(send), recv_at = displacements(recv);
    std::vector<char> in(size_t(recv_at.back()) + size_t(recv.back()));
    check(MPI_Alltoallv(out.data(), send.data(), send_at.data(), MPI_BYTE, in.data(), recv.data(), recv_at.data(),
                        MPI_BYTE, MPI_COMM_WORLD),
          "MPI_Alltoallv");
    return in;
  }
  void broadcast(std::string& s, int root) override {
    int n = int(s.size());
    check(MPI_Bcast(&n, 1, MPI_INT, root, MPI_COMM_WORLD), "MPI_Bcast");
    s.resize(size_t(n));
    check(MPI_Bcast(s.data(), n, MPI_CHAR, root, MPI_COMM_WORLD), "MPI_Bcast");
  }

 private:
  int rank_ = 0, size_ = 1;
};

// The exchange's messages carry their offset to the receiver, so that the
// counts and records a rank sends to me + d are received as coming from
// me - d: tag d + kSelf.
int send_tag(int k) { return k; }
int recv_tag(int k) { return kPeers - 1 - k; }

class MpiTransport final : public ParticleTransport {
 public:
  explicit MpiTransport(Comm& comm) : rank_(comm.rank()) {}
  ~MpiTransport() override {
    int done = 0;
    MPI_Finalized(&done);
    if (done) return;
    for (auto& t : types_) MPI_Type_free(&t.second);
  }
  void max(float* v, int n) override {
    check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_FLOAT, MPI_MAX, MPI_COMM_WORLD), "MPI_Allreduce");
  }
  void sum(double* v, int n) override {
    check(MPI_Allreduce(MPI_IN_PLACE, v, n, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD), "MPI_Allreduce");
  }
  void exchange_counts(const SlabBounds& b, const PeerCounts& send, PeerCounts& recv) override {
    uint32_t out[kPeers][2], in[kPeers][2] = {};
    std::vector<MPI_Request> req;
    for (int k = 0; k < kPeers; ++k) {
      if (k == kSelf || !b.exists[k]) continue;
      out[k][0] = send.total[k];
      out[k][1] = send.owned[k];
      req.emplace_back();
      check(MPI_Isend(out[k], 2, MPI_UINT32_T, rank_ + k - kSelf, send_tag(k), MPI_COMM_WORLD, &req.back()), "MPI_Isend");
      req.emplace_back();
      check(MPI_Irecv(in[k], 2, MPI_UINT32_T, rank_ + k - kSelf, recv_tag(k), MPI_COMM_WORLD, &req.back()), "MPI_Irecv");
    }
    check(MPI_Waitall(int(req.size()), req.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
    for (int k = 0; k < kPeers; ++k) {
      recv.total[k] = in[k][0];
      recv.owned[k] = in[k][1];
    }
  }
  void exchange_records(const SlabBounds& b, size_t record_bytes, const void* const send[kPeers],
                        const uint32_t send_count[kPeers], void* const recv[kPeers],
                        const uint32_t recv_count[kPeers], void* /*stream: the CPU backend's memory*/) override {
    const MPI_Datatype record = record_type(record_bytes);
    std::vector<MPI_Request> req;
    for (int k = 0; k < kPeers; ++k) {
      if (k == kSelf || !b.exists[k]) continue;
      const int peer = rank_ + k - kSelf;
      if (send_count[k] > 0) {
        req.emplace_back();
        check(MPI_Isend(send[k], int(send_count[k]), record, peer, send_tag(k), MPI_COMM_WORLD, &req.back()),
              "MPI_Isend");
      }
      if (recv_count[k] > 0) {
        req.emplace_back();
        check(MPI_Irecv(recv[k], int(recv_count[k]), record, peer, recv_tag(k), MPI_COMM_WORLD, &req.back()),
              "MPI_Irecv");
      }
    }
    check(MPI_Waitall(int(req.size()), req.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  }

 private:
  // A contiguous type of `bytes`, made once per record size (counts are ints:
  // 2^31 records, not bytes).
  MPI_Datatype record_type(size_t bytes) {
    for (const auto& t : types_)
      if (t.first == bytes) return t.second;
    MPI_Datatype type{};
    check(MPI_Type_contiguous(int(bytes), MPI_BYTE, &type), "MPI_Type_contiguous");
    check(MPI_Type_commit(&type), "MPI_Type_commit");
    types_.emplace_back(bytes, type);
    return type;
  }

  int rank_;
  std::vector<std::pair<size_t, MPI_Datatype>> types_;
};

}  // namespace

std::unique_ptr<ParticleTransport> make_mpi_transport(Comm& comm) { return std::make_unique<MpiTransport>(comm); }

bool mpi_built() { return true; }

int world_rank() {
  int ready = 0, finished = 0, rank = 0;
  MPI_Initialized(&ready);
  MPI_Finalized(&finished);
  if (ready && !finished) MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  return rank;
}

bool several_ranks() {
  int ready = 0, finished = 0, size = 1;
  MPI_Initialized(&ready);
  MPI_Finalized(&finished);
  if (ready && !finished) MPI_Comm_size(MPI_COMM_WORLD, &size);
  return size > 1;
}

void abort_ranks(int code) {
  if (several_ranks()) MPI_Abort(MPI_COMM_WORLD, code);
}

std::unique_ptr<Comm> make_mpi_comm() { return std::make_unique<MpiComm>(); }

}  // namespace sphray
