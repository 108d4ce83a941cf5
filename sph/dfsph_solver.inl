// The divergence-free SPH solver (dfsph.h), written once for both backends.
// Included by solver_cpu.cpp and solver_cuda.cu after solver_impl.inl, inside
// the backend namespace (GatherParticles, sort_and_offsets, the copies).
// One step: the step size from the largest speed (ChooseFlowStep); the
// explicit forces; the pressure solve on the neighbours of the step's start
// and the advection; the grid sort and the pair masks at the new positions;
// the density pass (density, factor, presence); the divergence solve. The
// grid then matches the positions until the next step, and every pass of
// the next step's pressure solve reuses its masks.
// A decomposed run (set_slab, dist/slab_solver.h): the particles are
// exchanged after the advection, before the sort (each rank owns those in
// its slab and holds copies of its neighbours' within one support of it, all
// the neighbours its own particles read until the next exchange); the
// ghosts take their owners' values of what the next pass reads from its
// neighbours (GhostRefresh, exchange_impl.inl): the velocities after the
// forces and after the step, the pressures after the warm start and every
// update, the accelerations before every update; the solves' residuals and
// the step's statistics are summed over the ranks, so every rank iterates
// and steps alike.

class DfsphSolverImpl final : public Solver {
 public:
  explicit DfsphSolverImpl(const SolverInput& in)
      : prm_(in.params), df_(in.dfsph), grid_(in.grid), cfl_(in.cfl), min_dt_(in.min_dt), max_dt_(in.max_dt),
        n_(uint32_t(in.fluid_pos_rho.size())), obstacles_(make_obstacle_set(kBackend, in.obstacles, in.params.spacing)),
        walls_(in, in.grid), transport_(in.transport) {
    t_ = in.start_time;
    steps_ = in.start_step;
    const size_t n = n_;
    upload(pos_, in.fluid_pos_rho);
    upload(vel_, in.fluid_vel);
    upload(id_, initial_ids(in, "DFSPH"));
    warm_.assign(n, Float4{0, 0, 0, 0});
    pos_tmp_.resize(n); vel_tmp_.resize(n); warm_tmp_.resize(n); id_tmp_.resize(n);
    status_.assign(n, uint8_t(kStatusOk)); status_tmp_.resize(n);
    acc_.resize(n);
    press_.assign(n, 0.0f); factor_.resize(n); source_.resize(n); residual_.resize(n); error_.assign(n, 0.0f);
    sparse_.resize(n);
    if (walls_.size()) wall_sum_.resize(n);
    keys_.resize(n); order_.resize(n);
    offsets_.resize(size_t(grid_.num_cells()) + 1);
    fine_offsets_.resize(size_t(grid_.num_fine_cells()) + 1);
    mask_words_ = in.pair_mask_words >= 0 ? uint32_t(in.pair_mask_words)
                                          : pair_mask_capacity(double(grid_.cell_size) / double(prm_.spacing));
    pairs_.resize(size_t(mask_words_) * n);
    pair_count_.resize(n);
    set_presence(in.presence);
    sort_and_mask();
    density(presence_mode_ == PresenceMode::EveryStep);
    reduce_stats();
  }

  Backend backend() const override { return kBackend; }
  SolverKind kind() const override { return SolverKind::Dfsph; }
  double time() const override { return t_; }
  uint64_t steps() const override { return steps_; }
  size_t num_fluid() const override { return n_ - ghosts_; }
  size_t num_removed() const override { return removed_; }
  uint64_t num_clamped() const override { return 0; }  // the walls are mirrors and a projection, not a guard
  const StepLimits& last_limits() const override { return limits_; }
  const StageTimes& last_stage_times() const override { return times_; }
  SolveStats last_solve() const override { return solve_; }
  bool has_presence() const override { return presence_valid_; }
  PresenceMode presence_mode() const override { return presence_mode_; }
  void set_presence(PresenceMode mode) override {
    presence_mode_ = mode;
    if (mode != PresenceMode::Off && presence_.size() < 6 * size_t(n_)) {
      presence_.resize(6 * size_t(n_));
      presence_tmp_.resize(6 * size_t(n_));
    }
  }

  ParticleView view() const override {
    return {kBackend, n_, raw(pos_), raw(offsets_), presence_valid_ ? raw(presence_) : nullptr, grid_,
            raw(fine_offsets_)};
  }

  size_t device_bytes() const override {
    auto b = [](const auto& v) { return v.size() * sizeof(typename std::decay_t<decltype(v)>::value_type); };
    return b(pos_) + b(vel_) + b(warm_) + b(pos_tmp_) + b(vel_tmp_) + b(warm_tmp_) + b(acc_) + b(presence_) +
           b(presence_tmp_) + b(press_) + b(factor_) + b(source_) + b(residual_) + b(error_) + b(sparse_) + b(id_) +
           b(id_tmp_) + b(status_) + b(status_tmp_) + b(keys_) + b(order_) + b(offsets_) + b(fine_offsets_) +
           b(pairs_) + b(pair_count_) + b(wall_sum_) + walls_.bytes() + raw_copies_.bytes() + lists_.bytes() +
           exchange_.bytes() + refresh_.bytes();
  }

  void step(double until) override {
    // Presence on every step that may reach `until` (as PbfSolverImpl::step).
    const bool presence_now =
        presence_mode_ == PresenceMode::EveryStep ||
        (presence_mode_ == PresenceMode::AtUntil && t_ + ChooseFlowStep::kLandSlack * max_dt_ >= until - 1e-12);
    obstacles_.view.time = float(t_);
    clock_.start();
    FlowControl* control = raw(control_);
    parallel_for("dfsph_choose_step", 1,
                 ChooseFlowStep{cfl_ * prm_.spacing, double(df_.speed_floor), max_dt_, double(df_.max_dt_viscous), min_dt_,
                                std::max(until - t_, 0.0), control, 0.0});
    forces();
    refresh(vel_);
    parallel_for("dfsph_warm_pressure", n_, DfsphWarmStart<false>{control, raw(warm_), raw(source_), raw(press_)});
    refresh(press_);
    SolveResult pressure = iterate<false>(df_.min_iterations, df_.max_iterations, df_.tolerance);
    kick<true>();
    pos_.swap(pos_tmp_);
    clock_.end_of("pairs");
    walls_.move(obstacles_.view, control);
    if (transport_) {
      exchange();
      clock_.end_of("exchange");
    }
    sort_and_mask();
    clock_.end_of("grid");
    density(presence_now, control);
    parallel_for("dfsph_warm_divergence", n_, DfsphWarmStart<true>{control, raw(warm_), raw(source_), raw(press_)});
    refresh(press_);
    SolveResult divergence = iterate<true>(1, df_.max_divergence_iterations, df_.divergence_tolerance);
    kick<false>();
    refresh(vel_);  // the next step's forces read the neighbours' velocities
    reduce_stats();
    control_read_.start(control);
    clock_.end_of("integrate");
    clock_.finish();
    const FlowControl& c = control_read_.value();
    if (c.outcome == kStepBelowFloor)
      throw SimulationError(describe_flow_dt_floor(c.limits, min_dt_, cfl_, t_, steps_));
    check_flow_state("DFSPH", "lower sph.cfl or raise dfsph.max_iterations", c.stats, steps_, t_, pos_, vel_, id_);
    limits_ = c.limits;
    times_ = {clock_.ms("grid"), clock_.ms("pairs"), clock_.ms("integrate")};
    times_.exchange = transport_ ? clock_.ms("exchange") : 0.0;
    solve_.iterations = pressure.iterations;
    solve_.divergence_iterations = divergence.iterations;
    solve_.density_error_mean = c.stats.count > 0 ? c.stats.error_sum / c.stats.count : 0.0;
    solve_.density_error_max = c.stats.error_max;
    solve_.converged = pressure.converged && divergence.converged;
    t_ += limits_.dt;
    ++steps_;
  }

  // A decomposed run: this rank's slab. The exchange at once (collective),
  // then the grid and the density pass with the ghosts, so that the next
  // step starts as every later one does.
  void set_slab(const SlabBounds& bounds) override {
    if (!transport_) throw std::logic_error("DFSPH: set_slab without a transport (SolverInput::transport)");
    if (bounds.halo_free < df_.kernel.support()) throw std::logic_error("DFSPH: a halo narrower than its support");
    bounds_ = bounds;
    exchange();
    sort_and_mask();
    density(false, steps_ > 0 ? raw(control_) : nullptr);
    reduce_stats();
  }

  FlowSums flow_sums() const override { return reduce_flow_sums(n_, pos_, vel_, status_); }
  std::vector<double> axis_counts(int axis, double lo, double bin, size_t bins) const override {
    return owned_axis_counts(n_, pos_, status_, axis, lo, bin, bins);
  }

  HostParticles download() const override {
    HostParticles h = download_particles(id_, pos_, vel_, presence_valid_ ? &presence_ : nullptr, n_);
    if (transport_) h.status = sphray::SPHRAY_BK::download(status_, n_);  // which are ghosts
    return h;
  }
  void download_raw(RawParticles& out, bool velocity, bool presence) const override {
    raw_copies_.take(out, pos_, vel_, id_, presence && presence_valid_ ? &presence_ : nullptr, n_, velocity);
  }
  std::vector<Vec3f> boundary_positions() const override { return walls_.positions(); }

  // p = rho0 d^2 p~ of the last step (p~ the pressure and the divergence
  // solves' variables summed, [m^2/s^2], dfsph.h: both push over the step).
  // Zero before the first step: no solve has run (and there is no dt).
  std::vector<float> pressures() const override {
    if (steps_ == 0) return std::vector<float>(n_, 0.0f);
    const std::vector<Float4> w = sphray::SPHRAY_BK::download(warm_, n_), p = sphray::SPHRAY_BK::download(pos_, n_);
    std::vector<float> out(n_);
    const DfsphPressureOf of{prm_.rest_density, float(1.0 / (limits_.dt * limits_.dt)), p.data(), w.data(), out.data()};
    for (uint32_t i = 0; i < n_; ++i) of(i);
    return out;
  }
  const float* device_pressure() override {
    if (pressure_out_.size() < n_) pressure_out_.resize(n_);
    // Zero before the first step: no solve has run (and there is no dt).
    const float inv_dt2 = steps_ == 0 ? 0.0f : float(1.0 / (limits_.dt * limits_.dt));
    parallel_for("dfsph_pressure", n_,
                 DfsphPressureOf{prm_.rest_density, inv_dt2, raw(pos_), raw(warm_), raw(pressure_out_)});
    return raw(pressure_out_);
  }

 private:
  PairMask pairs() { return {raw(pairs_), raw(pair_count_), n_, mask_words_}; }
  FlowArrays arrays() {
    return {pos_, vel_, warm_, pos_tmp_, vel_tmp_, warm_tmp_, id_, id_tmp_, status_, status_tmp_, presence_, presence_tmp_};
  }

  struct SolveResult {
    int iterations = 0;
    bool converged = false;
  };

  // Sorts every particle array by the cell of its position, drops the
  // particles outside the grid (an open top only), and builds the pair masks
  // within the support (the grid's cells are two supports wide).
  // After an exchange it also drops what the exchange sent away and lists
  // the ghosts' owners (GhostRefresh).
  void sort_and_mask() {
    static constexpr const char* kNames[2] = {"dfsph_keys", "dfsph_gather"};
    const FlowSort r = sort_flow_particles(kNames, grid_, prm_.open_top, n_, pos_, {presence_valid_}, arrays(), keys_,
                                           order_, fine_offsets_, &offsets_, gone_);
    gone_ = false;
    removed_ += r.dropped_owned;
    ghosts_ -= r.dropped_ghosts;
    n_ = r.active;
    if (transport_) refresh_.build(bounds_, raw(pos_), status_, id_, n_, *transport_);
    const float s = df_.kernel.support();
    BuildPairMask b{grid_, raw(fine_offsets_), raw(pos_), raw(pos_), s * s, true, pairs()};
    b.search_radius = s;
    parallel_for("dfsph_pair_masks", n_, b);
    // Every neighbour pass until the next sort reads these positions.
    lists_.classify(n_, prm_, s, 0.0f, walls_.view(), pairs(), raw(pos_));
  }


  // v* = v + dt (g + viscosity), into vel_.
  void forces() {
    const FlowControl* control = raw(control_);
    if (df_.viscosity <= 0) {
      parallel_for("dfsph_gravity", n_,
                   DfsphGravity{prm_, control, raw(pos_), raw(vel_), walls_.view(), raw(wall_sum_)});
      return;
    }
    static constexpr const char* kNames[3] = {"dfsph_viscosity", "dfsph_viscosity_walls",
                                              "dfsph_viscosity_direct"};
    mirror_pass_launches<DfsphViscosity>(kNames, lists_, false, prm_, df_, grid_, raw(fine_offsets_), pairs(), control,
                                         raw(pos_), raw(vel_), raw(vel_tmp_), walls_.view(), raw(wall_sum_));
    vel_.swap(vel_tmp_);
  }

  // The exchange (exchange_impl.inl) at the positions: the particles this
  // rank holds until the next, unsorted (sort_and_mask follows).
  void exchange() {
    const ConstParticleArrays s{raw(pos_), raw(vel_), raw(warm_), raw(id_), raw(status_), nullptr};
    const ExchangeResult r = exchange_particles(exchange_, bounds_, grid_, nullptr, *transport_, s, raw(pos_),
                                                raw(status_), n_, [&](uint32_t n) {
                                                  fit(n);
                                                  return ParticleArrays{raw(pos_), raw(vel_), raw(warm_), raw(id_),
                                                                        raw(status_), nullptr};
                                                });
    n_ = r.n;
    ghosts_ = r.ghosts;
    gone_ = true;
    presence_valid_ = false;  // the exchange carries none
  }

  // Grows every per-particle buffer to hold n particles, keeping the
  // contents (grow_to: a tenth to spare, as a decomposed run's count changes
  // every step).
  void fit(uint32_t n) {
    for (auto* v : {&pos_, &vel_, &warm_, &pos_tmp_, &vel_tmp_, &warm_tmp_, &acc_}) grow_to(*v, n);
    for (auto* v : {&press_, &factor_, &source_, &residual_, &error_}) grow_to(*v, n);
    for (auto* v : {&id_, &id_tmp_, &keys_, &order_, &pair_count_}) grow_to(*v, n);
    for (auto* v : {&status_, &status_tmp_, &sparse_}) grow_to(*v, n);
    if (walls_.size()) grow_to(wall_sum_, n);
    grow_to(pairs_, size_t(mask_words_) * n);
    if (presence_mode_ != PresenceMode::Off) {
      grow_to(presence_, 6 * size_t(n));
      grow_to(presence_tmp_, 6 * size_t(n));
    }
  }

  // The ghosts of a decomposed run take their owners' values of `values`.
  template <class T>
  void refresh(Vector<T>& values) {
    if (transport_) refresh_.refresh(values, *transport_);
  }

  // The density pass (dfsph.h, DfsphDensity) into pos_ (density), factor_,
  // source_, sparse_, error_ and, when asked for, presence_.
  void density(bool presence, const FlowControl* control = nullptr) {
    presence_valid_ = presence;
    static constexpr const char* kNames[3] = {"dfsph_density", "dfsph_density_walls",
                                              "dfsph_density_direct"};
    float* pr = presence ? raw(presence_) : nullptr;
    auto launch = [&](auto pass) {
      using P = decltype(pass);
      mirror_pass_launches<P::template pass>(kNames, lists_, walls_.size() > 0, prm_, df_, grid_, raw(fine_offsets_),
                                             pairs(), raw(pos_), raw(vel_), raw(pos_tmp_), raw(factor_), raw(source_),
                                             raw(sparse_), raw(error_), pr, n_, walls_.view(), raw(wall_sum_),
                                             raw(warm_), control);
    };
    if (presence) launch(WithFlag<true, DfsphDensity>{});
    else launch(WithFlag<false, DfsphDensity>{});
    pos_.swap(pos_tmp_);
  }

  template <bool WithSource>
  void accel() {
    static constexpr const char* kNames[3] = {"dfsph_accel", "dfsph_accel_walls",
                                              "dfsph_accel_direct"};
    static constexpr const char* kSourceNames[3] = {"dfsph_accel_source", "dfsph_accel_source_walls",
                                                    "dfsph_accel_source_direct"};
    mirror_pass_launches<WithFlag<WithSource, DfsphAccel>::template pass>(
        WithSource ? kSourceNames : kNames, lists_, walls_.size() > 0, prm_, df_, grid_, raw(fine_offsets_), pairs(),
        raw(control_), raw(pos_), raw(vel_), raw(press_), raw(acc_), raw(source_), walls_.view(), raw(wall_sum_));
  }

  // The iterations of one solve (dfsph.h): at least min_it, at most max_it,
  // until the mean residual is at most tol. The first pressure iteration
  // also computes the density the velocities lead to.
  template <bool Divergence>
  SolveResult iterate(int min_it, int max_it, double tol) {
    static constexpr const char* kNames[3] = {"dfsph_update", "dfsph_update_walls",
                                              "dfsph_update_direct"};
    static constexpr const char* kDivNames[3] = {"dfsph_update_div", "dfsph_update_div_walls",
                                                 "dfsph_update_div_direct"};
    SolveResult r;
    for (int k = 0; k < max_it;) {
      if (!Divergence && k == 0) accel<true>();
      else accel<false>();
      refresh(acc_);
      mirror_pass_launches<WithFlag<Divergence, DfsphUpdate>::template pass>(
          Divergence ? kDivNames : kNames, lists_, walls_.size() > 0, prm_, df_, grid_, raw(fine_offsets_), pairs(),
          raw(control_), raw(pos_), raw(acc_), raw(factor_), raw(source_), raw(sparse_), raw(press_), raw(residual_),
          walls_.view(), raw(wall_sum_));
      refresh(press_);
      ++k;
      // The residual is read on the host: one reduction per iteration.
      const double mean = mean_over_run(residual_, n_, ghosts_, status_, transport_);
      r.iterations = k;
      r.converged = mean <= tol;
      if (r.converged && k >= min_it) break;
    }
    return r;
  }

  // v += dt a of the solve's final pressure; after the pressure solve also
  // the advection into pos_tmp_.
  template <bool Advect>
  void kick() {
    accel<false>();
    parallel_for(Advect ? "dfsph_advect" : "dfsph_kick", n_,
                 DfsphKick<Advect>{prm_, raw(control_), raw(acc_), raw(press_), raw(vel_), raw(warm_), raw(pos_), raw(pos_tmp_),
                                   obstacles_.view, walls_.view(), df_.wall_margin});
  }

  // Speed, density error and finiteness of the current state, into the
  // control that the next step's size is chosen from.
  void reduce_stats() { reduce_flow_stats(n_, pos_, vel_, error_, status_, id_, transport_, &raw(control_)->stats); }


  SphParams prm_;
  DfsphParams df_;
  GridGeom grid_;
  double cfl_, min_dt_, max_dt_;
  uint32_t n_;
  ObstacleSet obstacles_;  // meshes the particles' paths stop at (obstacles.h)
  WallParticles walls_;    // the obstacles' (mesh_walls.h)
  PresenceMode presence_mode_ = PresenceMode::Off;
  bool presence_valid_ = false;
  double t_ = 0;
  uint64_t steps_ = 0;
  size_t removed_ = 0;
  StepLimits limits_;
  StageTimes times_;
  SolveStats solve_;
  StageClock clock_;
  Vector<FlowControl> control_ = Vector<FlowControl>(1);
  ReadBack<FlowControl> control_read_;
  mutable RawCopies raw_copies_;
  // pos_: x, density; vel_: v; warm_: the solves' last pressures (x: pressure,
  // y: divergence) as p dt^2, sorted with the particles; acc_: a of the solve.
  Vector<Float4> pos_, vel_, warm_, pos_tmp_, vel_tmp_, warm_tmp_, acc_;
  Vector<float> presence_, presence_tmp_, press_, factor_, source_, residual_, error_;
  Vector<float> pressure_out_;  // device_pressure
  Vector<uint8_t> sparse_;
  Vector<WallSum> wall_sum_;  // per particle near the obstacles' walls (dfsph.h)
  Vector<uint32_t> id_, id_tmp_, keys_, order_, offsets_, fine_offsets_;
  Vector<uint8_t> status_, status_tmp_;
  uint32_t mask_words_ = 0;
  Vector<PairWord> pairs_;
  Vector<uint32_t> pair_count_;
  LaunchLists lists_;  // the neighbour passes' particles per launch (flow_solver.inl), with the masks
  // A decomposed run (set_slab): the transport, the slabs (halo: the
  // support), the exchange's buffers, the ghosts' refresh lists, and how
  // many of the n_ particles are ghosts.
  ParticleTransport* transport_ = nullptr;
  SlabBounds bounds_;
  ExchangeBuffers exchange_;
  GhostRefresh refresh_;
  uint32_t ghosts_ = 0;
  bool gone_ = false;  // the arrays hold particles the last exchange sent away
};
