// A decomposed run's per-step traffic as the solver sees it (the ranks and
// their slabs are dist/'s, slab_solver.h): which particles go where after a
// step, and the transport that carries them (MPI on the CPU backend, NCCL on
// CUDA). The solver does the work on its own backend, so on CUDA the
// particles never leave the GPU.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/vec.h"

namespace sphray {

// A particle as it travels between ranks: what the next step reads of it.
struct ExchangeRecord {
  Float4 pos, vel, flow;  // x, density; v; u, p / rho^2 (integrate.h)
  uint32_t id;
  uint32_t status;  // integrate.h; kStatusGhost for a copy
};

// Ranks a particle can go to in one exchange: its owner is this rank or a
// neighbour (a step moves it less than a slab), and its ghost copies go to
// the owner's neighbours: ranks me - 2 .. me + 2, index k = rank - me + 2.
constexpr int kPeers = 5;
constexpr int kSelf = 2;

// The slabs of ranks me - 2 .. me + 2 along the cut axis (exists: the rank
// is in the run; the first and last slabs reach to infinity outward), and the
// width of their halos: `halo` where a particle lies near wall particles
// (their pressure, summed from the fluid within a support, reaches one
// support further), `halo_free` elsewhere.
struct SlabBounds {
  int axis = 0;
  float lo[kPeers] = {}, hi[kPeers] = {};
  bool exists[kPeers] = {};
  float halo = 0, halo_free = 0;
  // PBF's passes on a rank whose ghosts are at least this share of its
  // particles skip the ghosts and send the values the peers read while the
  // rest of the pass runs (PbfSolverImpl::iteration_pass); below it, the
  // whole pass and then the refresh. 0: always; above 1: never.
  float overlap_above = kOverlapAuto;
  static constexpr float kOverlapAuto = 0.06f, kOverlapNever = 2.0f;
};

// The bits of a particle id in a decomposed run: PBF's and DFSPH's ghost
// refresh lists sort keys of two bits of list and these (exchange_impl.inl,
// GhostRefresh::build); a run with larger ids is refused at its start
// (make_slab_solver).
constexpr int kRankIdBits = 30;

// A point's coordinate along axis 0 (x), 1 (y) or 2 (z).
SPHRAY_HD inline float along(const Vec3f& p, int axis) { return axis == 0 ? p.x : axis == 1 ? p.y : p.z; }

// The bin of coordinate x among `bins` (>= 1) bins `bin` wide from `lo`, the
// first and last holding what lies beyond: the balance's histogram
// (dist/slabs.h, AxisHistogram; Solver::axis_counts).
SPHRAY_HD inline uint32_t axis_bin(double x, double lo, double bin, uint32_t bins) {
  const double k = floor((x - lo) / bin);
  return k < 0 ? 0u : k >= double(bins - 1) ? bins - 1 : uint32_t(k);
}

// Where each particle goes: bit k of `to` for peer k; `owner` the peer that
// owns it. near_walls: wall particles lie within a support of p.
struct Destinations {
  uint8_t to, owner;
};

SPHRAY_HD inline Destinations destinations_of(const SlabBounds& b, const Float4& p, bool near_walls) {
  const float halo = near_walls ? b.halo : b.halo_free;
  const float x = along(xyz(p), b.axis);
  uint8_t owner = kSelf;
  if (b.exists[kSelf - 1] && x < b.lo[kSelf]) owner = kSelf - 1;
  else if (b.exists[kSelf + 1] && x >= b.hi[kSelf]) owner = kSelf + 1;
  uint8_t to = uint8_t(1u << owner);
  for (int k : {int(owner) - 1, int(owner) + 1}) {
    if (k < 0 || k >= kPeers || !b.exists[k]) continue;
    const float gap = x < b.lo[k] ? b.lo[k] - x : x >= b.hi[k] ? x - b.hi[k] : 0.0f;
    if (gap < halo) to = uint8_t(to | (1u << k));
  }
  return {to, owner};
}

// Per peer, the records this rank sends it, and how many of them it will own.
struct PeerCounts {
  uint32_t total[kPeers];
  uint32_t owned[kPeers];
};

// Carries records and reductions between the ranks, on the solver's
// backend memory (device pointers on CUDA). Collective: every rank calls.
class ParticleTransport {
 public:
  virtual ~ParticleTransport() = default;
  // In place, element-wise maximum over all ranks.
  virtual void max(float* values, int n) = 0;
  // In place, element-wise sum over all ranks.
  virtual void sum(double* values, int n) = 0;
  // Sends `send` (host) to each existing peer k != kSelf and returns in
  // `recv` (host) what each sent here.
  virtual void exchange_counts(const SlabBounds& b, const PeerCounts& send, PeerCounts& recv) = 0;
  // send[k]: send_count[k] records of record_bytes each for peer k; recv[k]:
  // room for recv_count[k] of them. On CUDA, `stream` (a cudaStream_t) orders
  // the transfers among the device's work; null: the legacy default stream,
  // where the solvers' kernels run. The CPU backend's transport ignores it.
  virtual void exchange_records(const SlabBounds& b, size_t record_bytes, const void* const send[kPeers],
                                const uint32_t send_count[kPeers], void* const recv[kPeers],
                                const uint32_t recv_count[kPeers], void* stream) = 0;
  // The same for records of type T.
  template <class T>
  void exchange(const SlabBounds& b, T* const send[kPeers], const uint32_t send_count[kPeers], T* const recv[kPeers],
                const uint32_t recv_count[kPeers], void* stream = nullptr) {
    const void* s[kPeers];
    void* r[kPeers];
    for (int k = 0; k < kPeers; ++k) {
      s[k] = send[k];
      r[k] = recv[k];
    }
    exchange_records(b, sizeof(T), s, send_count, r, recv_count, stream);
  }
};

}  // namespace sphray
