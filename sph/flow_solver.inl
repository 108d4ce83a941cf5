// What the two incompressible solvers (pbf_solver.inl, dfsph_solver.inl) do
// alike with their particle arrays: the sort by cell, and the guards' reports.
// Included inside a backend namespace (Vector, raw, read_one, parallel_for,
// sort_and_offsets, GatherParticles) after solver_impl.inl.

// A solver's sorted particle arrays and their scratch twins; `flow` is its
// own per-particle Float4 (PBF: x*, lambda; DFSPH: the warm-start pressures).
struct FlowArrays {
  Vector<Float4>&pos, &vel, &flow, &pos_tmp, &vel_tmp, &flow_tmp;
  Vector<uint32_t>&id, &id_tmp;
  Vector<uint8_t>&status, &status_tmp;
  Vector<float>&presence, &presence_tmp;
};

// What a sort kept and dropped (sort_flow_particles).
struct FlowSort {
  uint32_t active = 0;          // the particles kept, sorted first
  uint32_t dropped_owned = 0;   // the run's own particles dropped (outside the grid): removed
  uint32_t dropped_ghosts = 0;  // another rank's ghosts dropped with them
};

// What a sort carries besides positions, ids and states, and whether its
// keys are computed already.
struct FlowSortCarry {
  bool presence = false;
  // PBF's step sort leaves the velocities out: its finishing pass writes
  // every particle's anew, and nothing reads them before (pbf_solver.inl).
  bool velocity = true;
  // keys[] already holds each particle's slab key on this grid (PBF's
  // Predict computes it where it places the particle).
  bool keys_given = false;
};

// Sorts every array by the cell of `by` (one of them, read before the
// gather), carrying what `carry` says, into the slab table `fine_offsets`
// and, if given, the cell table `offsets`, and drops the particles outside
// the grid (an open top only) and, after an exchange (`exchanged`:
// exchange_impl.inl), those it sent away (kStatusGone). Without the
// velocities carried, vel keeps the order before the sort.
inline FlowSort sort_flow_particles(const char* const (&names)[2], const GridGeom& grid, bool open_top, uint32_t n,
                                    const Vector<Float4>& by, FlowSortCarry carry, FlowArrays a, Vector<uint32_t>& keys,
                                    Vector<uint32_t>& order, Vector<uint32_t>& fine_offsets, Vector<uint32_t>* offsets,
                                    bool exchanged = false) {
  if (exchanged) parallel_for(names[0], n, KeyOfStaying{grid, raw(by), raw(a.status), raw(keys)});
  else if (!carry.keys_given) parallel_for(names[0], n, KeyOf<Float4>{grid, raw(by), raw(keys)});
  sort_and_offsets(grid, n, keys, order, fine_offsets, offsets);
  FlowSort r;
  r.active = open_top || exchanged ? read_one(fine_offsets, grid.num_fine_cells()) : n;
  r.dropped_owned = n - r.active;
  if (exchanged && r.active < n) {
    const auto dropped = thrust::make_permutation_iterator(a.status.begin(), order.begin() + r.active);
    r.dropped_ghosts = uint32_t(thrust::count(policy(), dropped, dropped + (n - r.active), uint8_t(kStatusGhost)));
    const uint32_t sent = uint32_t(thrust::count(policy(), dropped, dropped + (n - r.active), uint8_t(kStatusGone)));
    r.dropped_owned -= r.dropped_ghosts + sent;
  }
  const ConstParticleArrays in{raw(a.pos), carry.velocity ? raw(a.vel) : nullptr, raw(a.flow), raw(a.id),
                               raw(a.status), carry.presence ? raw(a.presence) : nullptr};
  const ParticleArrays out{raw(a.pos_tmp), raw(a.vel_tmp), raw(a.flow_tmp), raw(a.id_tmp), raw(a.status_tmp),
                           raw(a.presence_tmp)};
  parallel_for(names[1], r.active, GatherParticles{raw(order), in, n, out, r.active});
  a.pos.swap(a.pos_tmp); a.flow.swap(a.flow_tmp); a.id.swap(a.id_tmp);
  a.status.swap(a.status_tmp);
  if (carry.velocity) a.vel.swap(a.vel_tmp);
  if (carry.presence) a.presence.swap(a.presence_tmp);
  return r;
}

// A per-particle value (PBF's density error, DFSPH's residual), another
// rank's ghosts' none: a decomposed run's sums count its own particles.
struct OwnedError {
  const float* error;
  const uint8_t* status;
  SPHRAY_HD double operator()(uint32_t i) const { return status[i] == kStatusGhost ? 0.0 : double(error[i]); }
};

// The mean of `values` over the run's own particles (0 without any): over
// the n here, or, with a transport (a decomposed run), over every rank's own
// particles (n - ghosts here). Read on the host: it decides the iterations.
inline double mean_over_run(const Vector<float>& values, uint32_t n, uint32_t ghosts, const Vector<uint8_t>& status,
                            ParticleTransport* transport) {
  double sum[2] = {0.0, double(n)};
  if (!transport) {
    sum[0] = thrust::reduce(policy(), values.begin(), values.begin() + n, 0.0);
  } else {
    sum[0] = thrust::transform_reduce(policy(), thrust::counting_iterator<uint32_t>(0),
                                      thrust::counting_iterator<uint32_t>(n), OwnedError{raw(values), raw(status)},
                                      0.0, thrust::plus<double>());
    sum[1] = double(n - ghosts);
    transport->sum(sum, 2);
  }
  return sum[1] > 0 ? sum[0] / sum[1] : 0.0;
}

// Speed, density error (error[]) and finiteness of the n particles into
// *stats, on the device; a decomposed run's over all ranks (its own
// particles only: status marks the ghosts), so that every rank takes the
// same step. first_bad stays the rank's own: the rank that has one raises
// the step's error (check_flow_state); so do the fastest particle's id and
// place (a run over several ranks reports them as unknown, dist/slab_solver.cpp).
inline void reduce_flow_stats(uint32_t n, const Vector<Float4>& pos, const Vector<Float4>& vel,
                              const Vector<float>& error, const Vector<uint8_t>& status, const Vector<uint32_t>& id,
                              ParticleTransport* transport, FlowStats* stats) {
  transform_reduce_into(n, FlowStatsOf{raw(pos), raw(vel), raw(error), transport ? raw(status) : nullptr, raw(id)},
                        CombineFlowStats(), kEmptyFlowStats, stats);
  if (!transport) return;
  static_assert(offsetof(FlowStats, error_max) == offsetof(FlowStats, max_speed2) + sizeof(float) &&
                    offsetof(FlowStats, count) == offsetof(FlowStats, error_sum) + sizeof(double),
                "the extremes and the sums are reduced as two arrays");
  transport->max(&stats->max_speed2, 2);
  transport->sum(&stats->error_sum, 2);
}

// A non-finite value, or a density error that no longer means anything (the
// liquid compressed to twice its rest density on average), ends the run:
// throws SimulationError naming the step (and the particle), with `remedy`.
inline void check_flow_state(const char* solver, const char* remedy, const FlowStats& s, uint64_t steps, double t,
                             const Vector<Float4>& pos, const Vector<Float4>& vel, const Vector<uint32_t>& id) {
  constexpr double kDivergedError = 1.0;
  const double mean = s.count > 0 ? s.error_sum / s.count : 0.0;
  if (s.first_bad == kNoBadParticle && mean <= kDivergedError) return;
  std::ostringstream os;
  if (s.first_bad != kNoBadParticle) {
    const uint32_t i = s.first_bad;
    const Float4 p = read_one(pos, i), v = read_one(vel, i);
    os << "non-finite position, density or velocity at step " << steps << " (t = " << t << " s) in particle "
       << read_one(id, i) << " (initial index): position (" << p.x << ", " << p.y << ", " << p.z << "), density "
       << p.w << ", velocity (" << v.x << ", " << v.y << ", " << v.z << ").";
  } else {
    os << "the " << solver << " density error diverged at step " << steps << " (t = " << t << " s): mean compression "
       << 100 * mean << "% (largest " << 100 * s.error_max << "%), above " << 100 * kDivergedError << "%.";
  }
  os << " The run is stopped rather than continued with garbage; " << remedy << ".";
  throw SimulationError(os.str());
}

// A decomposed run's particles fall in three groups for the passes whose
// values the ghosts take from their owners after the pass (PBF's iterations,
// LaunchLists::classify with the refresh's lists): the run's own particles
// that no peer holds a ghost of, those that some peer does (their values are
// sent as soon as their launch is done, while the others' runs), and the
// ghosts (no need to compute what the refresh overwrites). A run on one rank
// has the first group only.
enum LaunchGroup : int { kGroupRest = 0, kGroupListed = 1, kGroupGhosts = 2 };
constexpr int kLaunchGroups = 3;

// The class of a particle (mirror_walls.h, launch_class) at its position.
struct LaunchClassOf {
  SphParams prm;
  float support, margin;
  WallsView walls;
  PairMask pairs;
  const Float4* pos;
  SPHRAY_HD uint8_t operator()(uint32_t i) const {
    return launch_class(prm, support, margin, walls, pairs, i, xyz(pos[i]));
  }
};

// A decomposed run's classes, plus 4 times each particle's group.
struct ClassifyLaunch {
  LaunchClassOf cls_of;
  const uint8_t* status;
  const uint8_t* peer_bits;  // GhostRefresh::peer_bits
  uint8_t* cls;
  SPHRAY_HD void operator()(uint32_t i) const {
    const int g = status[i] == kStatusGhost ? kGroupGhosts : (peer_bits[i] & kToPeers) ? kGroupListed : kGroupRest;
    cls[i] = uint8_t(cls_of(i) + 4 * g);
  }
};

// Counts of the particles of each class and group (a decomposed run's
// lists) before a position: c[2 g] interior, c[2 g + 1] near walls,
// c[kDirectCount] the direct loop's of every group. (A scan keeps the lists in grid order: appended by
// atomics, the warps' runs came in the device's order and the 1M passes lost
// 4-8% to the scattered reads.)
struct LaunchCounts {
  uint32_t c[2 * kLaunchGroups + 1];
};
struct CountLaunch {
  SPHRAY_HD LaunchCounts operator()(uint8_t code) const {
    LaunchCounts r{};
    const int cls = code & 3, g = code >> 2;
    if (cls == kClassDirect) r.c[2 * kLaunchGroups] = 1u;
    else r.c[2 * g + cls] = 1u;
    return r;
  }
};
struct AddLaunchCounts {
  SPHRAY_HD LaunchCounts operator()(const LaunchCounts& a, const LaunchCounts& b) const {
    LaunchCounts r;
    for (int k = 0; k < 2 * kLaunchGroups + 1; ++k) r.c[k] = a.c[k] + b.c[k];
    return r;
  }
};

// The lists of the classes and groups: interior[g], near[g], direct; counts
// [2 g] and [2 g + 1] their lengths, [kDirectCount] the direct loop's.
constexpr int kDirectCount = 2 * kLaunchGroups;
struct LaunchListPtrs {
  uint32_t* interior[kLaunchGroups];
  uint32_t* near[kLaunchGroups];
  uint32_t* direct;
  uint32_t* counts;
};

// Each particle into its list, in grid order; the last particle writes the
// lists' lengths.
struct ScatterLaunchLists {
  const uint8_t* cls;
  const LaunchCounts* before;
  uint32_t n;
  LaunchListPtrs out;
  SPHRAY_HD void operator()(uint32_t i) const {
    const uint8_t code = cls[i];
    const int c = code & 3, g = code >> 2;
    const LaunchCounts& b = before[i];
    if (c == kClassInterior) out.interior[g][b.c[2 * g]] = i;
    else if (c == kClassNearWalls) out.near[g][b.c[2 * g + 1]] = i;
    else out.direct[b.c[kDirectCount]] = i;
    if (i + 1 == n) {
      for (int k = 0; k < kLaunchGroups; ++k) {
        out.counts[2 * k] = b.c[2 * k] + (c == kClassInterior && g == k ? 1u : 0u);
        out.counts[2 * k + 1] = b.c[2 * k + 1] + (c == kClassNearWalls && g == k ? 1u : 0u);
      }
      out.counts[kDirectCount] = b.c[kDirectCount] + (c == kClassDirect ? 1u : 0u);
    }
  }
};

// The near-wall and the interior particles of a pass (of one group) in one
// launch: the first threads serve the near-wall list, the next the interior
// list (the lengths on the device, so the host need not wait for them). One
// launch, so that the near-wall particles' slower work runs beside the
// interior work instead of after it with too few warps to fill the GPU (at
// 125k particles a quarter of them are near a wall), and first, so that it
// does not trail at the end.
template <class Interior, class Near>
struct ListedLaunch {
  static constexpr int kMaxRegisters =
      Interior::kMaxRegisters > Near::kMaxRegisters ? Interior::kMaxRegisters : Near::kMaxRegisters;
  Interior interior_pass;
  Near near_pass;
  const uint32_t* interior;
  const uint32_t* near;
  const uint32_t* counts;  // [2]: interior, near
  SPHRAY_HD void operator()(uint32_t k) const {
    const uint32_t n_near = counts[1];
    if (k < n_near) near_pass(near[k]);
    else if (k - n_near < counts[0]) interior_pass(interior[k - n_near]);
  }
};

// The direct loop's particles (overflowed masks: usually none), by a few
// threads that stride over their list (a full-size grid of mostly idle
// threads, once per pass, cost a 125k step several percent); not
// launched at all when the list is empty (LaunchLists::direct_count).
constexpr uint32_t kDirectThreads = 4096;
template <class Pass>
struct StridedLaunch {
  static constexpr int kMaxRegisters = Pass::kMaxRegisters;
  Pass pass;
  const uint32_t* list;
  const uint32_t* count;
  uint32_t stride;
  SPHRAY_HD void operator()(uint32_t t) const {
    for (uint32_t k = t; k < *count; k += stride) pass(list[k]);
  }
};

// The launches' particles over the passes that share one grid (mirror_walls.h).
class LaunchLists {
 public:
  // Classifies the n particles at pos, which move at most `margin` over
  // those passes, into the interior, near-wall and direct lists (in grid
  // order). A decomposed run whose passes are followed by a ghost refresh
  // also gives the particles' status and the refresh's peer bits
  // (GhostRefresh), and bounds on the listed particles and the ghosts (the
  // host's sizes of their launches): the lists are then kept per group.
  void classify(uint32_t n, const SphParams& prm, float support, float margin, const WallsView& walls,
                const PairMask& pairs, const Float4* pos, const uint8_t* status = nullptr,
                const uint8_t* peer_bits = nullptr, uint32_t listed_bound = 0, uint32_t ghosts = 0) {
    n_ = n;
    grouped_ = status != nullptr;
    if (grouped_ && !side_) side_ = std::make_unique<SideStream>();
    listed_bound_ = std::min(listed_bound, n);
    ghosts_bound_ = std::min(ghosts, n);
    if (direct_.size() < n) {
      interior_[0].resize(n);
      near_[0].resize(n);
      direct_.resize(n);
    }
    if (grouped_) {
      if (cls_.size() < n) cls_.resize(n);
      for (int g = 1; g < kLaunchGroups; ++g) {
        if (interior_[g].size() < n) interior_[g].resize(n);
        if (near_[g].size() < n) near_[g].resize(n);
      }
    }
    direct_known_ = n == 0;
    direct_count_ = 0;
    if (n == 0) return;
    const LaunchClassOf cls_of{prm, support, margin, walls, pairs, pos};
    if (grouped_) {
      parallel_for("launch_classes", n, ClassifyLaunch{cls_of, status, peer_bits, raw(cls_)});
      scatter();
    } else {  // one group: one pass (CUB's three-way partition on the GPU)
      partition_three("launch_lists", n, cls_of, raw(interior_[0]), raw(near_[0]), raw(direct_), raw(counts_),
                      raw(counts_) + kDirectCount);
    }
    direct_read_.start(raw(counts_) + kDirectCount);
  }
  // The direct loop's particles (usually none): read once per grid, when
  // the first pass asks, so that a pass launches no empty direct loop (six or
  // seven a PBF step, sixteen a DFSPH step, a few microseconds each). The host
  // waits only for the lists; the pass launched before the question runs on.
  uint32_t direct_count() const {
    if (!direct_known_) {
      direct_count_ = direct_read_.wait();
      direct_known_ = true;
    }
    return direct_count_;
  }
  uint32_t size() const { return n_; }
  bool grouped() const { return grouped_; }
  // The stream of the groups' small launches beside the large one (made with the first grouped lists).
  SideStream& side() const { return *side_; }
  // Threads enough for group g's launch (the host's bound on its length).
  uint32_t bound(LaunchGroup g) const {
    return g == kGroupRest ? n_ : !grouped_ ? 0u : g == kGroupListed ? listed_bound_ : ghosts_bound_;
  }
  template <class Interior, class Near>
  ListedLaunch<Interior, Near> listed(const Interior& a, const Near& b, LaunchGroup g = kGroupRest) const {
    return {a, b, raw(interior_[g]), raw(near_[g]), raw(counts_) + 2 * g};
  }
  template <class Pass>
  StridedLaunch<Pass> direct(const Pass& p) const {
    return {p, raw(direct_), raw(counts_) + kDirectCount, direct_threads()};
  }
  uint32_t direct_threads() const { return n_ < kDirectThreads ? n_ : kDirectThreads; }
  size_t bytes() const {
    size_t b = cls_.size() + before_.size() * sizeof(LaunchCounts) + direct_.size() * sizeof(uint32_t) +
               counts_.size() * sizeof(uint32_t);
    for (int g = 0; g < kLaunchGroups; ++g) b += (interior_[g].size() + near_[g].size()) * sizeof(uint32_t);
    return b;
  }

 private:
  // The groups' lists from the classes in cls_, by a scan of their counts.
  void scatter() {
    if (before_.size() < n_) before_.resize(n_);
    thrust::transform_exclusive_scan(policy(), cls_.begin(), cls_.begin() + n_, before_.begin(), CountLaunch{},
                                     LaunchCounts{}, AddLaunchCounts{});
    LaunchListPtrs out{{}, {}, raw(direct_), raw(counts_)};
    for (int g = 0; g < kLaunchGroups; ++g) {
      out.interior[g] = raw(interior_[g]);
      out.near[g] = raw(near_[g]);
    }
    parallel_for("launch_lists", n_, ScatterLaunchLists{raw(cls_), raw(before_), n_, out});
  }

  uint32_t n_ = 0;
  bool grouped_ = false;
  std::unique_ptr<SideStream> side_;
  uint32_t listed_bound_ = 0, ghosts_bound_ = 0;
  Vector<uint8_t> cls_;  // grouped runs only
  Vector<LaunchCounts> before_;
  Vector<uint32_t> interior_[kLaunchGroups], near_[kLaunchGroups], direct_;
  Vector<uint32_t> counts_ = Vector<uint32_t>(kDirectCount + 1);
  ReadBack<uint32_t> direct_read_;
  mutable bool direct_known_ = true;
  mutable uint32_t direct_count_ = 0;
};

// A neighbour pass (mirror_walls.h, MirrorPass) over group g's particles:
// the near-wall and the interior variant in one launch, the near-wall one
// with the obstacles' wall terms where the scene has obstacles' wall
// particles (`mesh`), on `side` where given (else the default stream).
// names: that launch without and with the obstacles' wall terms, and the
// direct loop's.
template <template <int> class Pass, class... Args>
void mirror_group_launch(const char* const (&names)[3], const LaunchLists& lists, bool mesh, LaunchGroup g,
                         SideStream* side, Args... args) {
  const uint32_t n = lists.bound(g);
  if (mesh) launch_on(side, names[1], n, lists.listed(Pass<kInterior>{args...}, Pass<kNearMesh>{args...}, g));
  else launch_on(side, names[0], n, lists.listed(Pass<kInterior>{args...}, Pass<kNearWalls>{args...}, g));
}

// The direct loop's launch of a pass (every group's particles whose masks overflowed).
template <template <int> class Pass, class... Args>
void mirror_direct_launch(const char* const (&names)[3], const LaunchLists& lists, SideStream* side, Args... args) {
  if (lists.direct_count() > 0)
    launch_on(side, names[2], lists.direct_threads(), lists.direct(Pass<kDirect>{args...}));
}

// A neighbour pass over every particle. A decomposed run's groups: the
// small launches (the particles peers read, the ghosts, the direct loop) on
// the lists' side stream beside the large one, so that they do not add
// their latency to it.
template <template <int> class Pass, class... Args>
void mirror_pass_launches(const char* const (&names)[3], const LaunchLists& lists, bool mesh, Args... args) {
  if (!lists.grouped()) {
    mirror_group_launch<Pass>(names, lists, mesh, kGroupRest, nullptr, args...);
    mirror_direct_launch<Pass>(names, lists, nullptr, args...);
    return;
  }
  SideStream& side = lists.side();
  side.fork();
  mirror_group_launch<Pass>(names, lists, mesh, kGroupListed, &side, args...);
  mirror_group_launch<Pass>(names, lists, mesh, kGroupRest, nullptr, args...);
  mirror_group_launch<Pass>(names, lists, mesh, kGroupGhosts, &side, args...);
  mirror_direct_launch<Pass>(names, lists, &side, args...);
  side.join();
}

// The message of a step below run.min_dt.
inline std::string describe_flow_dt_floor(const StepLimits& l, double min_dt, double cfl, double t, uint64_t steps) {
  std::ostringstream os;
  os << "time step " << l.dt << " s fell below the floor run.min_dt = " << min_dt << " s at t = " << t << " s (step "
     << steps << "): max speed " << l.max_speed << " m/s at sph.cfl = " << cfl
     << ". The flow is too fast for this resolution; raise sph.spacing or check the initial state.";
  return os.str();
}
