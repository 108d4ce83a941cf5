// A decomposed run's exchange of particles after a step (sph/exchange.h),
// written once for both backends. The particles that stay keep their slots:
// those that left are marked gone (kStatusGone, dropped by the grid's sort
// that follows, as particles outside the grid are), the ones that stay only
// as another rank's ghost are marked so, and what the peers send is appended.
// Only the particles that go somewhere are packed: a list of their indices,
// per peer a scan over that list, one scatter. The host reads two counts.
// Included inside a backend namespace by solver_impl.inl.

// near_walls: the grid's flags of cells with wall particles in reach
// (CellsNear; cells are a support wide), or null: near walls everywhere.
// pos: where the particles are placed (WCSPH, DFSPH: x; PBF: its prediction x*).
struct ClassifyForExchange {
  SlabBounds bounds;
  const Float4* pos;
  const uint8_t* status;
  GridGeom grid;
  const uint8_t* near_walls;
  Destinations* out;
  SPHRAY_HD void operator()(uint32_t i) const {
    // Ghosts go: their owners send them again where they are still wanted.
    if (status[i] == kStatusGhost) {
      out[i] = Destinations{0, uint8_t(kSelf)};
      return;
    }
    const Float4 p = pos[i];
    out[i] = destinations_of(bounds, p, near_walls == nullptr || cell_near(grid, near_walls, xyz(p)));
  }
};

struct CountDestinations {
  const Destinations* d;
  SPHRAY_HD PeerCounts operator()(uint32_t i) const {
    PeerCounts c{};
    for (int k = 0; k < kPeers; ++k) {
      c.total[k] = (d[i].to >> k) & 1u;
      c.owned[k] = d[i].to != 0 && d[i].owner == k ? 1u : 0u;
    }
    return c;
  }
};

struct AddPeerCounts {
  SPHRAY_HD PeerCounts operator()(const PeerCounts& a, const PeerCounts& b) const {
    PeerCounts c;
    for (int k = 0; k < kPeers; ++k) {
      c.total[k] = a.total[k] + b.total[k];
      c.owned[k] = a.owned[k] + b.owned[k];
    }
    return c;
  }
};

constexpr uint8_t kToPeers = uint8_t(0x1fu & ~(1u << kSelf));

// Particles with a destination other than this rank.
struct GoesToPeers {
  SPHRAY_HD bool operator()(const Destinations& d) const { return (d.to & kToPeers) != 0; }
};

// Per listed particle, how many records each peer has received up to it (inclusive).
struct CountPeerRecords {
  const Destinations* d;
  const uint32_t* list;
  SPHRAY_HD PeerCounts operator()(uint32_t j) const {
    PeerCounts c{};
    const Destinations dj = d[list[j]];
    for (int k = 0; k < kPeers; ++k) c.total[k] = k != kSelf && ((dj.to >> k) & 1u);
    return c;
  }
};

// Listed particle j into the buffer of each peer it goes to, at its place in
// the particles' order there: a ghost copy unless the peer owns it.
struct ScatterRecords {
  ConstParticleArrays s;
  const Destinations* d;
  const uint32_t* list;
  const PeerCounts* upto;  // inclusive scan of CountPeerRecords
  ExchangeRecord* out[kPeers];
  SPHRAY_HD void operator()(uint32_t j) const {
    const uint32_t i = list[j];
    const Destinations di = d[i];
    ExchangeRecord r{s.pos[i], s.vel[i], s.flow[i], s.id[i], uint32_t(kStatusGhost)};
    for (int k = 0; k < kPeers; ++k) {
      if (k == kSelf || !((di.to >> k) & 1u)) continue;
      r.status = di.owner == k ? uint32_t(s.status[i]) : uint32_t(kStatusGhost);
      out[k][upto[j].total[k] - 1u] = r;
    }
  }
};

// What stays of each particle here: as it is (owned), as a ghost, or gone.
struct MarkStaying {
  const Destinations* d;
  uint8_t* status;
  SPHRAY_HD void operator()(uint32_t i) const {
    const Destinations di = d[i];
    if (!((di.to >> kSelf) & 1u)) status[i] = kStatusGone;
    else if (di.owner != kSelf) status[i] = kStatusGhost;
  }
};

struct UnpackRecords {
  const ExchangeRecord* in;
  uint32_t offset;
  ParticleArrays out;
  SPHRAY_HD void operator()(uint32_t i) const {
    const ExchangeRecord r = in[i];
    const uint32_t j = offset + i;
    out.pos[j] = r.pos;
    out.vel[j] = r.vel;
    out.flow[j] = r.flow;
    out.id[j] = r.id;
    out.status[j] = uint8_t(r.status);
  }
};

// The buffers of the exchange, kept from step to step (they only grow).
struct ExchangeBuffers {
  Vector<Destinations> dest;
  Vector<PeerCounts> counts = Vector<PeerCounts>(1), upto;
  Vector<uint32_t> list;
  Vector<ExchangeRecord> send[kPeers], recv[kPeers];
  size_t bytes() const {
    size_t b = dest.size() * sizeof(Destinations) + upto.size() * sizeof(PeerCounts) + list.size() * sizeof(uint32_t);
    for (int k = 0; k < kPeers; ++k) b += (send[k].size() + recv[k].size()) * sizeof(ExchangeRecord);
    return b;
  }
};

// At least n elements, keeping the contents; a tenth more when it grows,
// so that a count that creeps up step by step does not reallocate (and copy)
// every step.
template <class T>
void grow_to(Vector<T>& v, size_t n) {
  if (v.size() < n) v.resize(n + n / 10);
}

// What an exchange left: the particles now in the arrays (gone ones
// included, until the grid drops them), and how many of the others are
// owned here and are ghosts.
struct ExchangeResult {
  uint32_t n = 0, owned = 0, ghosts = 0;
};

// Exchanges the n particles of `s`, placed at `place` (s.pos or s.flow),
// with the peers (near_walls: ClassifyForExchange); `fit(m)` grows the
// particle arrays to m (keeping their contents) and returns them, for the
// records received, appended after the n.
template <class Fit>
ExchangeResult exchange_particles(ExchangeBuffers& buf, const SlabBounds& bounds, const GridGeom& grid,
                                  const uint8_t* near_walls, ParticleTransport& transport, ConstParticleArrays s,
                                  const Float4* place, uint8_t* status, uint32_t n, Fit&& fit) {
  grow_to(buf.dest, n);
  parallel_for("exchange_classify", n,
               ClassifyForExchange{bounds, place, s.status, grid, near_walls, raw(buf.dest)});
  transform_reduce_into(n, CountDestinations{raw(buf.dest)}, AddPeerCounts(), PeerCounts{}, raw(buf.counts));
  const PeerCounts send = read_one(buf.counts, 0);
  // The particles that go to a peer, listed; per peer their places.
  grow_to(buf.list, n);
  const uint32_t m = uint32_t(thrust::copy_if(policy(), thrust::counting_iterator<uint32_t>(0),
                                              thrust::counting_iterator<uint32_t>(n), buf.dest.begin(),
                                              buf.list.begin(), GoesToPeers()) -
                              buf.list.begin());
  ScatterRecords scatter{s, raw(buf.dest), raw(buf.list), nullptr, {}};
  for (int k = 0; k < kPeers; ++k) {
    grow_to(buf.send[k], k == kSelf ? 0 : send.total[k]);
    scatter.out[k] = raw(buf.send[k]);
  }
  if (m > 0) {
    grow_to(buf.upto, m);
    thrust::transform_inclusive_scan(policy(), thrust::counting_iterator<uint32_t>(0),
                                     thrust::counting_iterator<uint32_t>(m), buf.upto.begin(),
                                     CountPeerRecords{raw(buf.dest), raw(buf.list)}, AddPeerCounts());
    scatter.upto = raw(buf.upto);
    parallel_for("exchange_pack", m, scatter);
  }
  parallel_for("exchange_mark", n, MarkStaying{raw(buf.dest), status});
  PeerCounts recv{};
  transport.exchange_counts(bounds, send, recv);
  ExchangeRecord* send_ptr[kPeers];
  ExchangeRecord* recv_ptr[kPeers];
  ExchangeResult r{n, send.owned[kSelf], send.total[kSelf] - send.owned[kSelf]};
  for (int k = 0; k < kPeers; ++k) {
    send_ptr[k] = raw(buf.send[k]);
    recv_ptr[k] = nullptr;
    if (k == kSelf) continue;
    grow_to(buf.recv[k], recv.total[k]);
    recv_ptr[k] = raw(buf.recv[k]);
    r.n += recv.total[k];
    r.owned += recv.owned[k];
    r.ghosts += recv.total[k] - recv.owned[k];
  }
  transport.exchange(bounds, send_ptr, send.total, recv_ptr, recv.total);
  const ParticleArrays out = fit(r.n);
  uint32_t offset = n;
  for (int k = 0; k < kPeers; ++k) {
    if (k == kSelf) continue;
    parallel_for("exchange_unpack", recv.total[k], UnpackRecords{raw(buf.recv[k]), offset, out});
    offset += recv.total[k];
  }
  return r;
}

// The ghosts of a decomposed run refreshed from their owners within a step
// (PBF's and DFSPH's iterations: each pass reads its neighbours' values from
// the pass before, and a ghost's own pass, short of the neighbours beyond
// the halo, would be wrong). After the step's exchange and sort, both
// sides list the same particles: the owner, per peer, those of its own whose
// destinations (destinations_of at the place they were exchanged by, with
// no wall flags: the halo `halo` everywhere) include that peer; the peer,
// its ghosts whose owner it is. The exchange gave every such peer
// its copy (it placed them by the same function at the same place), so the
// two lists hold the same ids; each is sorted by id (GhostRefresh::build:
// the four lists of a rank in one sort), so that the k-th record sent is
// the k-th ghost received. The counts are compared once per step: a
// mismatch is a logic error, not a hang.
struct PeerBits {
  SlabBounds bounds;
  const Float4* place;
  const uint8_t* status;
  uint8_t* bits;
  SPHRAY_HD void operator()(uint32_t i) const {
    const Destinations d = destinations_of(bounds, place[i], true);  // as exchange_particles without wall flags
    bits[i] = status[i] == kStatusGhost ? uint8_t(1u << d.owner) : uint8_t(d.to & kToPeers);
  }
};

template <class T>
struct PackByIndex {
  const T* values;
  const uint32_t* index;
  T* out;
  SPHRAY_HD void operator()(uint32_t j) const { out[j] = values[index[j]]; }
};

template <class T>
struct UnpackByIndex {
  const T* in;
  const uint32_t* index;
  T* values;
  SPHRAY_HD void operator()(uint32_t j) const { values[index[j]] = in[j]; }
};

// GhostRefresh's four lists: the owned particles a peer holds ghosts of (the
// slab below, the slab above) and the ghosts that peer owns here.
enum RefreshList : int { kSendBelow = 0, kSendAbove = 1, kRecvBelow = 2, kRecvAbove = 3, kRefreshLists = 4 };

struct RefreshCounts {
  uint32_t n[kRefreshLists];
};

struct AddRefreshCounts {
  SPHRAY_HD RefreshCounts operator()(const RefreshCounts& a, const RefreshCounts& b) const {
    RefreshCounts c;
    for (int l = 0; l < kRefreshLists; ++l) c.n[l] = a.n[l] + b.n[l];
    return c;
  }
};

// The lists particle i belongs to (PeerBits: a ghost's bit is its owner's).
SPHRAY_HD inline uint32_t refresh_lists_of(uint8_t bits, uint8_t status) {
  const bool below = (bits >> (kSelf - 1)) & 1u, above = (bits >> (kSelf + 1)) & 1u;
  return status == kStatusGhost ? (below ? 1u << kRecvBelow : 0u) | (above ? 1u << kRecvAbove : 0u)
                                : (below ? 1u << kSendBelow : 0u) | (above ? 1u << kSendAbove : 0u);
}

struct CountRefreshLists {
  const uint8_t* bits;
  const uint8_t* status;
  SPHRAY_HD RefreshCounts operator()(uint32_t i) const {
    const uint32_t m = refresh_lists_of(bits[i], status[i]);
    RefreshCounts c;
    for (int l = 0; l < kRefreshLists; ++l) c.n[l] = (m >> l) & 1u;
    return c;
  }
};

// Particle i into each of its lists, at its place there (upto: the
// inclusive scan of CountRefreshLists; the last element holds the lists'
// lengths), keyed by list and id: one sort then orders every list by id.
struct ScatterRefreshLists {
  const uint8_t* bits;
  const uint8_t* status;
  const uint32_t* id;
  const RefreshCounts* upto;
  uint32_t last;  // n - 1
  uint32_t* keys;
  uint32_t* index;
  SPHRAY_HD void operator()(uint32_t i) const {
    const uint32_t m = refresh_lists_of(bits[i], status[i]);
    if (m == 0) return;
    const RefreshCounts total = upto[last], at = upto[i];
    uint32_t base = 0;
    for (int l = 0; l < kRefreshLists; ++l) {
      if ((m >> l) & 1u) {
        const uint32_t j = base + at.n[l] - 1u;
        keys[j] = (uint32_t(l) << kRankIdBits) | id[i];
        index[j] = i;
      }
      base += total.n[l];
    }
  }
};

class GhostRefresh {
 public:
  // The lists of the particles as sorted now (after the step's exchange and
  // sort), placed at `place` as the exchange placed them.
  void build(const SlabBounds& bounds, const Float4* place, const Vector<uint8_t>& status, const Vector<uint32_t>& id,
             uint32_t n, ParticleTransport& transport) {
    bounds_ = bounds;
    grow_to(bits_, n);
    RefreshCounts lengths{};
    if (n > 0) {
      parallel_for("ghost_peers", n, PeerBits{bounds, place, raw(status), raw(bits_)});
      // Only the slabs beside this one: the halo is narrower than a slab
      // (plan_slabs), so ghosts' owners and owned particles' ghost holders
      // are neighbours. The four lists as segments of one array, in the
      // particles' order, then sorted by (list, id): one scan, one read of
      // the lengths, one sort.
      grow_to(upto_, n);
      thrust::transform_inclusive_scan(policy(), thrust::counting_iterator<uint32_t>(0),
                                       thrust::counting_iterator<uint32_t>(n), upto_.begin(),
                                       CountRefreshLists{raw(bits_), raw(status)}, AddRefreshCounts());
      lengths = read_one(upto_, n - 1);
    }
    uint32_t m = 0;
    for (int l = 0; l < kRefreshLists; ++l) m += lengths.n[l];
    grow_to(keys_, m);
    grow_to(index_, m);
    if (m > 0) {
      parallel_for("ghost_lists", n, ScatterRefreshLists{raw(bits_), raw(status), raw(id), raw(upto_), n - 1,
                                                         raw(keys_), raw(index_)});
      sort_pairs(keys_, index_, m, kRankIdBits + 2);
    }
    PeerCounts mine{}, theirs{};
    uint32_t at = 0;
    for (int l = 0; l < kRefreshLists; ++l) {
      const int k = l == kSendBelow || l == kRecvBelow ? kSelf - 1 : kSelf + 1;
      const bool send = l == kSendBelow || l == kSendAbove;
      (send ? send_at_ : recv_at_)[k] = at;
      (send ? send_n_ : recv_n_)[k] = bounds.exists[k] ? lengths.n[l] : 0u;
      at += lengths.n[l];
    }
    for (int k = 0; k < kPeers; ++k) {
      grow_to(send_buf_[k], send_n_[k]);
      grow_to(recv_buf_[k], recv_n_[k]);
      mine.total[k] = send_n_[k];
    }
    transport.exchange_counts(bounds, mine, theirs);
    for (int k = 0; k < kPeers; ++k)
      if (k != kSelf && bounds.exists[k] && theirs.total[k] != recv_n_[k])
        throw std::logic_error("ghost refresh: rank at offset " + std::to_string(k - kSelf) + " sends " +
                               std::to_string(theirs.total[k]) + " values for the " + std::to_string(recv_n_[k]) +
                               " ghosts it owns here");
  }

  // Every ghost's entry of `values` set to its owner's (T: at most a Float4,
  // packed into the Float4 buffers), in order on the default stream.
  template <class T>
  void refresh(Vector<T>& values, ParticleTransport& transport) {
    transfer(values, transport, nullptr);
  }

  // The same queued on `side` (SideStream), after what it holds: the caller
  // forks it so that the values this rank sends are written by then, and
  // nothing it queues on the default stream before side.join() may write
  // them or read or write the ghosts' entries (PBF's pass over the particles
  // that no peer holds a ghost of runs meanwhile, iteration_pass).
  template <class T>
  void refresh_beside(Vector<T>& values, ParticleTransport& transport, SideStream& side) {
    transfer(values, transport, &side);
  }

  // Per particle as sorted now, the peers it is listed for (PeerBits): an
  // owned particle with a bit other than kSelf's is one whose values some
  // peer reads.
  const uint8_t* peer_bits() const { return raw(bits_); }
  // At least the owned particles listed for a peer (the lists' lengths summed).
  uint32_t listed_bound() const {
    uint32_t m = 0;
    for (int k = 0; k < kPeers; ++k) m += send_n_[k];
    return m;
  }

  size_t bytes() const {
    size_t b = bits_.size() + (keys_.size() + index_.size()) * sizeof(uint32_t) + upto_.size() * sizeof(RefreshCounts);
    for (int k = 0; k < kPeers; ++k) b += (send_buf_[k].size() + recv_buf_[k].size()) * sizeof(Float4);
    return b;
  }

 private:
  // Pack, send and receive, unpack: on side's stream where given, else on the default one.
  template <class T>
  void transfer(Vector<T>& values, ParticleTransport& transport, SideStream* side) {
    static_assert(sizeof(T) <= sizeof(Float4) && alignof(T) <= alignof(Float4), "a value per particle, Float4 at most");
    T* send[kPeers];
    T* recv[kPeers];
    for (int k = 0; k < kPeers; ++k) {
      send[k] = reinterpret_cast<T*>(raw(send_buf_[k]));
      recv[k] = reinterpret_cast<T*>(raw(recv_buf_[k]));
      if (send_n_[k] > 0)
        launch_on(side, "ghost_pack", send_n_[k], PackByIndex<T>{raw(values), raw(index_) + send_at_[k], send[k]});
    }
    transport.exchange(bounds_, send, send_n_, recv, recv_n_, side ? side->stream() : nullptr);
    for (int k = 0; k < kPeers; ++k)
      if (recv_n_[k] > 0)
        launch_on(side, "ghost_unpack", recv_n_[k], UnpackByIndex<T>{recv[k], raw(index_) + recv_at_[k], raw(values)});
  }

  SlabBounds bounds_;
  Vector<uint8_t> bits_;
  Vector<RefreshCounts> upto_;
  // The lists, one after another (send below, send above, receive from
  // below, from above): keys (list, id) and the particles' indices.
  Vector<uint32_t> keys_, index_;
  uint32_t send_at_[kPeers] = {}, recv_at_[kPeers] = {};  // where each peer's lists start in index_
  Vector<Float4> send_buf_[kPeers], recv_buf_[kPeers];
  uint32_t send_n_[kPeers] = {}, recv_n_[kPeers] = {};
};

// The run's own particles (not ghosts, not gone) per bin (axis_bin) of
// `bin` metres along `axis` from `lo`: the balance of a decomposed
// run (SlabSolver::rebalance) without the particles leaving the device.
struct CountAlongAxis {
  const Float4* pos;
  const uint8_t* status;
  int axis;
  double lo, bin;
  uint32_t bins;
  uint32_t* counts;
  SPHRAY_HD void operator()(uint32_t i) const {
    if (status[i] == kStatusGhost || status[i] == kStatusGone) return;
    atomic_increment(counts + axis_bin(double(along(xyz(pos[i]), axis)), lo, bin, bins));
  }
};

inline std::vector<double> owned_axis_counts(uint32_t n, const Vector<Float4>& pos, const Vector<uint8_t>& status,
                                             int axis, double lo, double bin, size_t bins) {
  std::vector<double> out(bins, 0.0);
  if (bins == 0) return out;
  Vector<uint32_t> counts(bins, 0u);
  if (n > 0) parallel_for("axis_counts", n, CountAlongAxis{raw(pos), raw(status), axis, lo, bin, uint32_t(bins), raw(counts)});
  const std::vector<uint32_t> c = sphray::SPHRAY_BK::download(counts, bins);
  for (size_t k = 0; k < bins; ++k) out[k] = double(c[k]);
  return out;
}
