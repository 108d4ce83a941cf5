// One SPH step, written once for both backends. Included by solver_cpu.cpp and
// solver_cuda.cu inside their backend namespace (which supplies Vector, raw,
// policy, parallel_for, transform_reduce_into, ReadBack, upload, download, read_one,
// StageClock and kBackend).
// Stages: grid, pairs (forces, density rate and presence in one neighbour
// loop, interaction.h), integrate (integrate.h says why in that order). The
// grid is rebuilt at the end of a step (and once at construction), so between
// steps the cell table matches the positions exactly: the field builder reads
// both as they are (view()).

// Its dependencies come from stages.h, included first outside the namespace.

SPHRAY_HD SPHRAY_FORCEINLINE Vec3f position_of(const Float4& p) { return xyz(p); }
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f position_of(const Vec3f& p) { return p; }

// The particle data into the new sorted order, one kernel for all of it
// (one read of the order): out[i] = in[order[i]] for the first n_new sorted
// particles. Presence, when there is one, [6][n_old] -> [6][n_new].
struct GatherParticles {
  const uint32_t* order;
  const Float4 *pos, *vel, *flow;
  const uint32_t* id;
  const uint8_t* status;
  const float* presence;  // null: none to carry
  uint32_t n_old;
  Float4 *pos_out, *vel_out, *flow_out;
  uint32_t* id_out;
  uint8_t* status_out;
  float* presence_out;
  uint32_t n_new;
  SPHRAY_HD void operator()(uint32_t i) const {
    const uint32_t j = order[i];
    pos_out[i] = pos[j];
    vel_out[i] = vel[j];
    flow_out[i] = flow[j];
    id_out[i] = id[j];
    status_out[i] = status[j];
    if (presence)
      for (uint32_t k = 0; k < 6; ++k) presence_out[k * n_new + i] = presence[k * n_old + j];
  }
};

// Cell key of every point (particles as Float4, plain points as Vec3f).
template <class P>
struct KeyOf {
  GridGeom grid;
  const P* pts;
  uint32_t* keys;
  SPHRAY_HD void operator()(uint32_t i) const { keys[i] = grid.fine_key_of(position_of(pts[i])); }
};

// Coarse cell table from the slab table (grid.h): offsets[c] = fine[c * kSubX].
struct CoarseOffsets {
  const uint32_t* fine;
  uint32_t* coarse;
  SPHRAY_HD void operator()(uint32_t c) const { coarse[c] = fine[c * uint32_t(GridGeom::kSubX)]; }
};

// Sorts `n` fine keys with their order (stable, so both backends agree on the
// order within a slab; on the key bits in use) and fills fine[k] = first
// sorted index with key >= k, for k in [0, num_fine_cells]: one vectorised
// binary search per slab, parallel over slabs. (A scatter of the slab starts
// and a min-scan from the right gives the same table in the same time, 21-22
// us at 1M on the H100, in three kernels.) Then the coarse table, when one is
// asked for.
inline void sort_and_offsets(const GridGeom& g, uint32_t n, Vector<uint32_t>& keys, Vector<uint32_t>& order,
                             Vector<uint32_t>& fine, Vector<uint32_t>* coarse) {
  thrust::sequence(policy(), order.begin(), order.begin() + n);
  int bits = 1;  // the keys run up to num_fine_cells() (outside the grid)
  while (bits < 32 && (g.num_fine_cells() >> bits) != 0) ++bits;
  sort_pairs(keys, order, n, bits);
  thrust::lower_bound(policy(), keys.begin(), keys.begin() + n, thrust::counting_iterator<uint32_t>(0),
                      thrust::counting_iterator<uint32_t>(g.num_fine_cells() + 1), fine.begin());
  if (coarse) parallel_for(g.num_cells() + 1, CoarseOffsets{raw(fine), raw(*coarse)});
}

// Sorted keys back to coarse cell keys (for GridBuild).
struct CoarseKey {
  SPHRAY_HD uint32_t operator()(uint32_t k) const { return k / uint32_t(GridGeom::kSubX); }
};

inline GridBuild build_grid_impl(const GridGeom& g, const std::vector<Vec3f>& points) {
  const uint32_t n = uint32_t(points.size());
  Vector<Vec3f> pts;
  upload(pts, points);
  Vector<uint32_t> keys(n), order(n), offsets(size_t(g.num_cells()) + 1), fine(size_t(g.num_fine_cells()) + 1);
  parallel_for(n, KeyOf<Vec3f>{g, raw(pts), raw(keys)});
  sort_and_offsets(g, n, keys, order, fine, &offsets);
  thrust::transform(policy(), keys.begin(), keys.begin() + n, keys.begin(), CoarseKey());
  return {download(order, n), download(keys, n), download(offsets, offsets.size()), download(fine, fine.size())};
}

inline PairMaskBuild build_pair_masks_impl(const GridGeom& g, const std::vector<Vec3f>& points, float radius,
                                           uint32_t capacity, const std::vector<Vec3f>* queries,
                                           bool tensor_tiles = true) {
  PairMaskBuild out;
  out.grid = build_grid_impl(g, points);
  const uint32_t n = out.grid.offsets.back();  // points inside the grid, sorted first
  std::vector<Float4> sorted(n);
  for (uint32_t k = 0; k < n; ++k) {
    const Vec3f p = points[out.grid.order[k]];
    sorted[k] = {p.x, p.y, p.z, 0.0f};
  }
  // The queries: the sorted points themselves, or the given ones.
  std::vector<Float4> query_pts = sorted;
  if (queries) {
    query_pts.resize(queries->size());
    for (size_t k = 0; k < queries->size(); ++k) query_pts[k] = {(*queries)[k].x, (*queries)[k].y, (*queries)[k].z, 0.0f};
  }
  const uint32_t nq = uint32_t(query_pts.size());
  Vector<Float4> pts, qpts;
  Vector<uint32_t> fine;
  Vector<uint8_t> near;
  upload(pts, sorted);
  upload(qpts, query_pts);
  upload(fine, out.grid.fine_offsets);
  if (queries) {
    near.resize(g.num_cells());
    parallel_for(g.num_cells(), CellsNear{g, raw(fine), raw(near)});
  }
  Vector<PairWord> words(size_t(capacity) * nq);
  Vector<uint32_t> count(nq);
  const float r2 = radius * radius;
  parallel_for(nq, BuildPairMask{g, raw(fine), raw(pts), raw(qpts), r2, queries == nullptr,
                                 PairMask{raw(words), raw(count), nq, capacity}, queries ? raw(near) : nullptr,
                                 tensor_tiles});
  std::vector<PairWord> host_words = sphray::SPHRAY_BK::download(words, words.size());
  std::vector<uint32_t> host_count = sphray::SPHRAY_BK::download(count, nq);
  const PairMask m{host_words.data(), host_count.data(), nq, capacity};
  out.neighbours.resize(nq);
  for (uint32_t i = 0; i < nq; ++i) {
    auto visit = [&](uint32_t j, Float4, Vec3f, float) { out.neighbours[i].push_back(j); };
    const Vec3f x = xyz(query_pts[i]);
    const uint32_t skip = queries ? kNoSkip : i;
    if (masks_complete(m, m, i)) {
      for_each_pair<false>(g, out.grid.fine_offsets.data(), sorted.data(), x, r2, skip, m, i, visit);
    } else {
      ++out.overflowed;
      for_each_pair<true>(g, out.grid.fine_offsets.data(), sorted.data(), x, r2, skip, m, i, visit);
    }
  }
  return out;
}

class SolverImpl final : public Solver {
 public:
  explicit SolverImpl(const SolverInput& in)
      : prm_(in.params), grid_(in.grid), cfl_(in.cfl), min_dt_(in.min_dt), max_dt_(in.max_dt),
        n_(uint32_t(in.fluid_pos_rho.size())) {
    const size_t n = n_, cells = size_t(grid_.num_cells()) + 1, slabs = size_t(grid_.num_fine_cells()) + 1;
    upload(pos_, in.fluid_pos_rho);
    upload(vel_, in.fluid_vel);
    flow_ = vel_;  // u = v until there is an acceleration to predict with
    std::vector<uint32_t> ids(n);
    for (size_t i = 0; i < n; ++i) ids[i] = uint32_t(i);
    upload(id_, ids);
    pos_tmp_.resize(n); vel_tmp_.resize(n); flow_tmp_.resize(n); id_tmp_.resize(n);
    accel_.resize(n); rate_grad_.resize(n);
    status_.assign(n, uint8_t(kStatusOk)); status_tmp_.resize(n);
    keys_.resize(n); order_.resize(n); offsets_.resize(cells); fine_offsets_.resize(slabs);
    mask_words_ = in.pair_mask_words >= 0 ? uint32_t(in.pair_mask_words)
                                          : pair_mask_capacity(double(prm_.kernel.support()) / double(prm_.spacing));
    fluid_pairs_.resize(size_t(mask_words_) * n);
    boundary_pairs_.resize(size_t(mask_words_) * n);
    fluid_pair_count_.resize(n);
    boundary_pair_count_.resize(n);
    parallel_for(n_, PressureTermOf{prm_, raw(pos_), raw(flow_)});
    set_presence(in.presence);

    // Static walls: sorted by the same grid once.
    const uint32_t nb = uint32_t(in.boundary.size());
    Vector<Float4> boundary_in;
    upload(boundary_in, in.boundary);
    Vector<float> alpha_in;
    upload(alpha_in, in.boundary_alpha);
    Vector<uint32_t> bkeys(nb), border(nb);
    boundary_.resize(nb);
    boundary_alpha_.resize(nb);
    wall_.resize(nb);
    boundary_offsets_.resize(slabs);
    parallel_for(nb, KeyOf<Float4>{grid_, raw(boundary_in), raw(bkeys)});
    sort_and_offsets(grid_, nb, bkeys, border, boundary_offsets_, nullptr);
    thrust::gather(policy(), border.begin(), border.end(), boundary_in.begin(), boundary_.begin());
    thrust::gather(policy(), border.begin(), border.end(), alpha_in.begin(), boundary_alpha_.begin());
    boundary_near_.resize(grid_.num_cells());
    fluid_near_.resize(grid_.num_cells());
    parallel_for(grid_.num_cells(), CellsNear{grid_, raw(boundary_offsets_), raw(boundary_near_)});
    build_grid();
  }

  Backend backend() const override { return kBackend; }
  double time() const override { return t_; }
  uint64_t steps() const override { return steps_; }
  size_t num_fluid() const override { return n_; }
  size_t num_removed() const override { return removed_; }
  uint64_t num_clamped() const override {
    // Clamps of the last integration are not yet in clamped_total_.
    return clamped_total_ + uint64_t(thrust::count(policy(), status_.begin(), status_.begin() + n_, uint8_t(kStatusClamped)));
  }
  const StepLimits& last_limits() const override { return limits_; }
  const StageTimes& last_stage_times() const override { return times_; }
  bool has_presence() const override { return presence_valid_; }
  void set_presence(PresenceMode mode) override {
    presence_mode_ = mode;
    if (mode != PresenceMode::Off && presence_.size() < 6 * size_t(n_)) {  // allocated on first use only
      presence_.resize(6 * size_t(n_));
      presence_tmp_.resize(6 * size_t(n_));
    }
  }
  ParticleView view() const override {
    return {kBackend, n_, raw(pos_), raw(offsets_), presence_valid_ ? raw(presence_) : nullptr, grid_};
  }

  size_t device_bytes() const override {
    auto b = [](const auto& v) { return v.size() * sizeof(typename std::decay_t<decltype(v)>::value_type); };
    return b(pos_) + b(vel_) + b(flow_) + b(pos_tmp_) + b(vel_tmp_) + b(flow_tmp_) + b(accel_) + b(rate_grad_) + b(presence_) + b(presence_tmp_) + b(id_) +
           b(id_tmp_) + b(status_) + b(status_tmp_) + b(keys_) + b(order_) + b(offsets_) + b(fine_offsets_) + b(boundary_) +
           b(boundary_alpha_) + b(wall_) + b(boundary_offsets_) + b(fluid_pairs_) + b(boundary_pairs_) +
           b(fluid_pair_count_) + b(boundary_pair_count_) + b(fluid_near_) + b(boundary_near_) + b(snap_pos_) +
           b(snap_vel_) + b(snap_id_) + b(snap_presence_);
  }

  // Stage order: pairs (wall pressure, then one neighbour loop for the
  // acceleration, the density rate and presence), the step size from their
  // extremes, integrate (kick, density, drift), grid.
  void step(double until) override {
    // Presence is computed in the pair loop, before dt is known: on every
    // step that may reach `until` (dt can only be smaller than the bound).
    const bool presence_now = presence_mode_ == PresenceMode::EveryStep ||
                              (presence_mode_ == PresenceMode::AtUntil && t_ + dt_bound() >= until - 1e-12);
    clock_.mark(1);
    if (prm_.kernel.type == KernelType::WendlandC2) pairs<KernelType::WendlandC2>(presence_now);
    else pairs<KernelType::CubicSpline>(presence_now);
    presence_valid_ = presence_now;
    clock_.mark(2);
    // The step's size is chosen on the device (integrate.h, ChooseStep), so
    // that nothing waits for the host between the reduction and the kick; the
    // host reads the decision once the step's work is done, and raises its
    // error then (a refused step moves no particle).
    StepControl* control = raw(control_);
    transform_reduce_into(n_, StepStatsOf{raw(pos_), raw(vel_), raw(accel_), raw(status_)}, CombineStepStats(),
                          kEmptyStepStats, &control->stats);
    parallel_for(1, ChooseStep{step_rule(), min_dt_, std::max(until - t_, 0.0), control, raw(pos_), raw(vel_),
                               raw(accel_), raw(id_)});
    parallel_for(n_, Advance{prm_, control, raw(pos_), raw(vel_), raw(flow_), raw(accel_), raw(rate_grad_), raw(status_)});
    control_read_.start(control);
    clock_.mark(3);
    build_grid();
    clock_.mark(4);
    clock_.finish(4);
    const StepControl& c = control_read_.value();
    if (c.outcome == kStepBadParticle) throw SimulationError(describe_bad_particle(c));
    if (c.outcome == kStepSupersonic) throw SimulationError(describe_supersonic(c));
    clamped_total_ += c.stats.clamped;
    limits_ = c.limits;
    if (c.outcome == kStepBelowFloor) throw SimulationError(describe_dt_floor());
    times_ = {clock_.ms(3, 4), clock_.ms(1, 2), clock_.ms(2, 3)};
    t_ += limits_.dt;
    ++steps_;
  }

  HostParticles download() const override {
    HostParticles h;
    h.id = sphray::SPHRAY_BK::download(id_, n_);
    const auto p = sphray::SPHRAY_BK::download(pos_, n_), v = sphray::SPHRAY_BK::download(vel_, n_);
    h.pos.resize(n_); h.vel.resize(n_); h.density.resize(n_);
    for (size_t i = 0; i < n_; ++i) {
      h.pos[i] = xyz(p[i]);
      h.vel[i] = xyz(v[i]);
      h.density[i] = p[i].w;
    }
    if (presence_valid_) {
      const auto pr = sphray::SPHRAY_BK::download(presence_, 6 * size_t(n_));
      h.presence.resize(n_);
      for (size_t i = 0; i < n_; ++i)
        for (size_t k = 0; k < 6; ++k) h.presence[i][k] = pr[k * n_ + i];
    }
    return h;
  }

  // On CUDA the copies run behind the next steps (AsyncDownload): out.ready
  // waits for them.
  void download_raw(RawParticles& out, bool velocity, bool presence) const override {
    snapshot_.begin();
    auto copy = [&](const auto& src, auto& staging, auto& dst, size_t n) {
      dst.resize(n);  // pinned memory on CUDA (host_memory.h)
      if (n) snapshot_.copy(src, n, staging, dst.data());
    };
    copy(pos_, snap_pos_, out.pos, n_);
    copy(id_, snap_id_, out.id, n_);
    if (velocity) copy(vel_, snap_vel_, out.vel, n_);
    else out.vel.clear();
    if (presence && presence_valid_) copy(presence_, snap_presence_, out.presence, 6 * size_t(n_));
    else out.presence.clear();
    out.ready = snapshot_.done();
  }

  std::vector<Vec3f> boundary_positions() const override {
    const auto b = sphray::SPHRAY_BK::download(boundary_, boundary_.size());
    std::vector<Vec3f> out(b.size());
    for (size_t k = 0; k < b.size(); ++k) out[k] = xyz(b[k]);
    return out;
  }

  std::vector<uint32_t> download_cell_offsets() const override {
    return sphray::SPHRAY_BK::download(offsets_, offsets_.size());
  }

 private:
  template <bool P, bool Direct, KernelType K>
  Interaction<P, Direct, K> pair_stage() {
    return {prm_, grid_, raw(fine_offsets_), raw(pos_), raw(flow_), raw(boundary_offsets_), raw(boundary_), raw(wall_),
            raw(boundary_alpha_), fluid_pairs(), boundary_pairs(), raw(accel_), raw(rate_grad_),
            P ? raw(presence_) : nullptr, n_};
  }

  // The pairs stage: the wall pressure, then the pair loop. The kernel type K
  // is a template parameter of both loops (kernel.h, W_for and dW_over_r_for).
  template <KernelType K>
  void pairs(bool presence) {
    parallel_for(uint32_t(boundary_.size()), WallPressure<K>{prm_, grid_, raw(fine_offsets_), raw(pos_), raw(flow_),
                                                             raw(fluid_near_), raw(boundary_), raw(wall_)});
    if (presence) pair_launches<true, K>();
    else pair_launches<false, K>();
  }

  // The pair loop is two launches: the pair masks, then the direct loop for
  // the particles whose masks overflowed (neighbours.h; usually none).
  template <bool P, KernelType K>
  void pair_launches() {
    parallel_for(n_, pair_stage<P, false, K>());
    parallel_for(n_, pair_stage<P, true, K>());
  }

  PairMask fluid_pairs() { return {raw(fluid_pairs_), raw(fluid_pair_count_), n_, mask_words_}; }
  PairMask boundary_pairs() { return {raw(boundary_pairs_), raw(boundary_pair_count_), n_, mask_words_}; }

  void build_grid() {
    parallel_for(n_, KeyOf<Float4>{grid_, raw(pos_), raw(keys_)});
    sort_and_offsets(grid_, n_, keys_, order_, fine_offsets_, &offsets_);
    // Particles outside the grid (only possible through an open top: Advance
    // keeps them inside a closed tank, whose grid holds its walls besides)
    // sorted last: drop them. Reading their count waits for the sort, so a
    // closed tank does not.
    const uint32_t active = prm_.open_top ? read_one(offsets_, grid_.num_cells()) : n_;
    parallel_for(active, GatherParticles{raw(order_), raw(pos_), raw(vel_), raw(flow_), raw(id_), raw(status_),
                                         presence_valid_ ? raw(presence_) : nullptr, n_, raw(pos_tmp_), raw(vel_tmp_),
                                         raw(flow_tmp_), raw(id_tmp_), raw(status_tmp_), raw(presence_tmp_), active});
    pos_.swap(pos_tmp_);
    vel_.swap(vel_tmp_);
    flow_.swap(flow_tmp_);
    id_.swap(id_tmp_);
    status_.swap(status_tmp_);
    if (presence_valid_) presence_.swap(presence_tmp_);
    removed_ += n_ - active;
    n_ = active;
    parallel_for(grid_.num_cells(), CellsNear{grid_, raw(fine_offsets_), raw(fluid_near_)});
    // The pair masks of the next step's pair loop (neighbours.h), at these positions.
    const float support2 = prm_.kernel.support() * prm_.kernel.support();
    parallel_for(n_, BuildPairMask{grid_, raw(fine_offsets_), raw(pos_), raw(pos_), support2, true, fluid_pairs()});
    parallel_for(n_, BuildPairMask{grid_, raw(boundary_offsets_), raw(boundary_), raw(pos_), support2, false,
                                   boundary_pairs(), raw(boundary_near_)});
  }

  // The viscous limit of dt: 0.125 h^2 / nu with the 3D equivalent viscosity of
  // the artificial one (Monaghan 2005).
  double dt_viscous() const {
    const double h = prm_.kernel.h, nu_art = prm_.viscosity_alpha * h * prm_.speed_of_sound / 10.0;
    return nu_art > 0 ? 0.125 * h * h / nu_art : std::numeric_limits<double>::infinity();
  }

  // An upper bound of the next dt: the step rule at zero speed and acceleration.
  double dt_bound() const { return step_rule().limits(kEmptyStepStats).dt; }

  StepRule step_rule() const {
    return {double(prm_.kernel.h), double(prm_.speed_of_sound), cfl_, max_dt_, dt_viscous()};
  }

  // The message of a step refused for a dt below its floor (limits_ holds
  // what bounded it).
  std::string describe_dt_floor() const {
    const StepLimits& l = limits_;
    const char* by = l.dt_force < l.dt_cfl ? "the force limit" : "the CFL (sound speed) limit";
    std::ostringstream os;
    os << "time step " << l.dt << " s fell below the floor run.min_dt = " << min_dt_ << " s at t = " << t_
       << " s (step " << steps_ << "), bounded by " << by << ": max speed " << l.max_speed
       << " m/s, max acceleration " << l.max_accel << " m/s^2. The scene is too stiff or unstable at this "
       << "resolution; raise sph.spacing, lower the speed of sound or check the initial state.";
    return os.str();
  }

  std::string describe_supersonic(const StepControl& c) const {
    const Float4 p = c.bad_pos, v = c.bad_vel;
    std::ostringstream os;
    os << "particle " << c.bad_id << " (initial index) moves at " << c.limits.max_speed
       << " m/s, faster than the speed of sound c0 = " << prm_.speed_of_sound << " m/s, at step " << steps_
       << " (t = " << t_ << " s), position (" << p.x << ", " << p.y << ", " << p.z << "), velocity (" << v.x << ", "
       << v.y << ", " << v.z << "), density " << p.w << ". A weakly compressible fluid holds only well below its "
       << "speed of sound; the run is stopped rather than continued with meaningless results. Raise "
       << "sph.speed_of_sound (\"auto\" takes 10x the flow speed the scene can be expected to reach).";
    return os.str();
  }

  std::string describe_bad_particle(const StepControl& c) const {
    const Float4 p = c.bad_pos, v = c.bad_vel, a = c.bad_accel;
    const uint32_t id = c.bad_id;
    const char* what = !all_finite(xyz(p))   ? "position"
                       : !std::isfinite(p.w) ? "density"
                       : p.w <= 0            ? "density (not positive)"
                       : !all_finite(xyz(v)) ? "velocity"
                       : !all_finite(xyz(a)) ? "acceleration"
                                             : "density rate";
    std::ostringstream os;
    os << "non-finite or invalid " << what << " at step " << steps_ << " (t = " << t_ << " s) in particle " << id
       << " (initial index): position (" << p.x << ", " << p.y << ", " << p.z << "), density " << p.w
       << ", velocity (" << v.x << ", " << v.y << ", " << v.z << "), acceleration (" << a.x << ", " << a.y
       << ", " << a.z << "). The run is stopped rather than continued with garbage.";
    return os.str();
  }

  SphParams prm_;
  GridGeom grid_;
  double cfl_, min_dt_, max_dt_;
  uint32_t n_;
  PresenceMode presence_mode_ = PresenceMode::Off;
  bool presence_valid_ = false;
  double t_ = 0;
  uint64_t steps_ = 0;
  size_t removed_ = 0;
  uint64_t clamped_total_ = 0;
  StepLimits limits_;
  StageTimes times_;
  StageClock clock_;
  // The step's decision on the device (ChooseStep) and its copy for the host.
  Vector<StepControl> control_ = Vector<StepControl>(1);
  ReadBack<StepControl> control_read_;
  // download_raw's staging buffers and copies (allocated by the first export).
  mutable AsyncDownload snapshot_;
  mutable Vector<Float4> snap_pos_, snap_vel_;
  mutable Vector<uint32_t> snap_id_;
  mutable Vector<float> snap_presence_;

  // vel_: the exact velocity; flow_: what the pair loop reads of a neighbour,
  // u (the predicted kicked velocity) and p / rho^2 (integrate.h).
  Vector<Float4> pos_, vel_, flow_, pos_tmp_, vel_tmp_, flow_tmp_, accel_, rate_grad_, boundary_;
  Vector<float> presence_, presence_tmp_, boundary_alpha_;
  Vector<WallState> wall_;
  // offsets_: coarse cell table (view(), the field builder, the raycaster);
  // fine_offsets_ and boundary_offsets_: slab tables of the neighbour loops (grid.h).
  Vector<uint32_t> id_, id_tmp_, keys_, order_, offsets_, fine_offsets_, boundary_offsets_;
  // Pair masks of every fluid particle against the fluid and the walls (neighbours.h).
  uint32_t mask_words_ = 0;
  Vector<PairWord> fluid_pairs_, boundary_pairs_;
  Vector<uint32_t> fluid_pair_count_, boundary_pair_count_;
  Vector<uint8_t> status_, status_tmp_;
  // Per grid cell: whether fluid (updated with the grid) or wall particles
  // (static) lie in the 27 cells around it (CellsNear, grid.h).
  Vector<uint8_t> fluid_near_, boundary_near_;
};
