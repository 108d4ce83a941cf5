// A decomposed run's exchange of particles after a step (sph/exchange.h),
// written once for both backends: each particle's destinations, their
// counts, the records packed per peer in the particles' order, the
// transport, and the records unpacked into the particle arrays (kept ones
// first, then each peer's in rank order), all on the solver's backend.
// Included inside a backend namespace by solver_impl.inl.

struct ClassifyForExchange {
  SlabBounds bounds;
  const Float4* pos;
  const uint8_t* status;
  Destinations* out;
  SPHRAY_HD void operator()(uint32_t i) const {
    // A ghost's owner sends it again where it is still wanted.
    out[i] = status[i] == kStatusGhost ? Destinations{0, uint8_t(kSelf)} : destinations_of(bounds, pos[i]);
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

// Particle i into the buffer of each peer it goes to, at its place in the
// particles' order there (the inclusive scan of the counts, less one): a
// ghost copy unless the peer owns it.
struct ScatterRecords {
  ConstParticleArrays s;
  const Destinations* d;
  const PeerCounts* upto;  // inclusive scan of CountDestinations
  ExchangeRecord* out[kPeers];
  SPHRAY_HD void operator()(uint32_t i) const {
    const Destinations di = d[i];
    if (di.to == 0) return;
    ExchangeRecord r{s.pos[i], s.vel[i], s.flow[i], s.id[i], uint32_t(kStatusGhost)};
    for (int k = 0; k < kPeers; ++k) {
      if (!((di.to >> k) & 1u)) continue;
      r.status = di.owner == k ? uint32_t(s.status[i]) : uint32_t(kStatusGhost);
      out[k][upto[i].total[k] - 1u] = r;
    }
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
  Vector<PeerCounts> upto;
  Vector<ExchangeRecord> send[kPeers], recv[kPeers];
  size_t bytes() const {
    size_t b = dest.size() * sizeof(Destinations) + upto.size() * sizeof(PeerCounts);
    for (int k = 0; k < kPeers; ++k) b += (send[k].size() + recv[k].size()) * sizeof(ExchangeRecord);
    return b;
  }
};

template <class T>
void grow_to(Vector<T>& v, size_t n) {
  if (v.size() < n) v.resize(n);
}

// What an exchange left: the particles now held, and how many of them this rank owns.
struct ExchangeResult {
  uint32_t n = 0, owned = 0;
};

// Packs the particles of `s` (n of them) per destination, exchanges them,
// and unpacks what stays and what came into `out` (which the caller has
// grown via `fit`, called with the new count before unpacking).
template <class Fit>
ExchangeResult exchange_particles(ExchangeBuffers& buf, const SlabBounds& bounds, ParticleTransport& transport,
                                  ConstParticleArrays s, uint32_t n, Fit&& fit) {
  grow_to(buf.dest, n);
  grow_to(buf.upto, n);
  parallel_for("exchange_classify", n, ClassifyForExchange{bounds, s.pos, s.status, raw(buf.dest)});
  // One scan gives every particle its place in each peer's buffer, and in
  // its last element the counts (the one read the host waits for).
  PeerCounts send{};
  if (n > 0) {
    thrust::transform_inclusive_scan(policy(), thrust::counting_iterator<uint32_t>(0),
                                     thrust::counting_iterator<uint32_t>(n), buf.upto.begin(),
                                     CountDestinations{raw(buf.dest)}, AddPeerCounts());
    send = read_one(buf.upto, n - 1);
  }
  ScatterRecords scatter{s, raw(buf.dest), raw(buf.upto), {}};
  for (int k = 0; k < kPeers; ++k) {
    grow_to(buf.send[k], send.total[k]);
    scatter.out[k] = raw(buf.send[k]);
  }
  parallel_for("exchange_pack", n, scatter);
  PeerCounts recv{};
  transport.exchange_counts(bounds, send, recv);
  recv.total[kSelf] = send.total[kSelf];
  recv.owned[kSelf] = send.owned[kSelf];
  ExchangeRecord* send_ptr[kPeers];
  ExchangeRecord* recv_ptr[kPeers];
  for (int k = 0; k < kPeers; ++k) {
    send_ptr[k] = raw(buf.send[k]);
    if (k != kSelf) grow_to(buf.recv[k], recv.total[k]);
    recv_ptr[k] = k == kSelf ? nullptr : raw(buf.recv[k]);
  }
  transport.exchange(bounds, send_ptr, send.total, recv_ptr, recv.total);
  ExchangeResult r;
  for (int k = 0; k < kPeers; ++k) {
    r.n += recv.total[k];
    r.owned += recv.owned[k];
  }
  const ParticleArrays out = fit(r.n);
  uint32_t offset = 0;
  for (int k : {kSelf, 0, 1, 3, 4}) {  // the kept ones first, then each peer's
    const ExchangeRecord* from = k == kSelf ? raw(buf.send[kSelf]) : raw(buf.recv[k]);
    parallel_for("exchange_unpack", recv.total[k], UnpackRecords{from, offset, out});
    offset += recv.total[k];
  }
  return r;
}
