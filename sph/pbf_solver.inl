// The position-based fluids solver (pbf.h), written once for both backends.
// Included by solver_cpu.cpp and solver_cuda.cu after solver_impl.inl, inside
// the backend namespace (GatherParticles, sort_and_offsets, the copies).
// One step: the step size from the largest speed (ChooseFlowStep); predict;
// the grid sort and the pair masks at the predicted positions, found once
// and reused by every pass of the step; the constraint iterations; the
// finishing pass. The step sorts by a grid with cells of one support (the
// scene's grid halved, GridGeom::halved), where each pair-mask query tests
// about half the candidates of the scene's grid, whose cells are two
// supports wide so that the field's voxels are the same under every solver:
// the rows of the wide cells reach a support beyond the sphere on every
// side. The obstacles' wall particles stay on the scene's grid (WallsView
// carries it). (DFSPH steps on the scene's grid: its view reads the grid it
// steps on, and a re-sort for the view would cost its next step the masks
// and the density pass again.) The sort follows
// the predicted positions, so after a step the cell table is off by the
// step's corrections: view() sorts again by the final positions, on the
// scene's grid, before a later stage reads the grid (once per output frame,
// not per step).
// A decomposed run (set_slab, dist/slab_solver.h): the particles are
// exchanged after the prediction, placed at x* (each rank owns those in its
// slab, and holds copies of its neighbours' within one PBF support of it:
// the pair masks are found at x* and kept through the step, so these are
// all the neighbours its own particles read); after every pass of the
// iterations the ghosts take their owners' values (GhostRefresh,
// exchange_impl.inl; on a rank with many ghosts sent while the rest of the
// pass runs: iteration_pass), and the step's statistics are reduced over the
// ranks before the next step's size is chosen.

class PbfSolverImpl final : public Solver {
 public:
  explicit PbfSolverImpl(const SolverInput& in)
      : prm_(in.params), pbf_(in.pbf), grid_(in.grid), step_grid_(in.grid.halved()), cfl_(in.cfl), min_dt_(in.min_dt), max_dt_(in.max_dt),
        n_(uint32_t(in.fluid_pos_rho.size())), obstacles_(make_obstacle_set(kBackend, in.obstacles, in.params.spacing)),
        walls_(in, in.grid), transport_(in.transport) {
    t_ = in.start_time;
    steps_ = in.start_step;
    const size_t n = n_;
    upload(pos_, in.fluid_pos_rho);
    upload(vel_, in.fluid_vel);
    upload(id_, initial_ids(in, "PBF"));
    pred_.assign(n, Float4{0, 0, 0, 0});
    pos_tmp_.resize(n); vel_tmp_.resize(n); pred_tmp_.resize(n); id_tmp_.resize(n);
    status_.assign(n, uint8_t(kStatusOk)); status_tmp_.resize(n);
    error_.assign(n, 0.0f);
    if (walls_.size()) wall_grad_.resize(n);
    keys_.resize(n); order_.resize(n);
    offsets_.resize(size_t(grid_.num_cells()) + 1);
    fine_offsets_.resize(size_t(step_grid_.num_fine_cells()) + 1);  // either grid's slab table (sort_by)
    mask_words_ = in.pair_mask_words >= 0 ? uint32_t(in.pair_mask_words)
                                          : pair_mask_capacity(double(pbf_.kernel.s) / double(prm_.spacing));
    pairs_.resize(size_t(mask_words_) * n);
    pair_count_.resize(n);
    set_presence(in.presence);
    sort_by(pos_, false);  // the grid of the initial positions, for a view before the first step
    reduce_stats();
  }

  Backend backend() const override { return kBackend; }
  SolverKind kind() const override { return SolverKind::Pbf; }
  double time() const override { return t_; }
  uint64_t steps() const override { return steps_; }
  size_t num_fluid() const override { return n_ - ghosts_; }
  size_t num_removed() const override { return removed_; }
  uint64_t num_clamped() const override { return 0; }  // the walls are projections, not a guard
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

  // The grid must match the positions for the stages that read it: sorting
  // again is logically const (the same particles, in cell order).
  ParticleView view() const override {
    if (!grid_current_) const_cast<PbfSolverImpl*>(this)->sort_by(pos_, false);
    return {kBackend, n_, raw(pos_), raw(offsets_), presence_valid_ ? raw(presence_) : nullptr, grid_,
            raw(fine_offsets_)};
  }

  size_t device_bytes() const override {
    auto b = [](const auto& v) { return v.size() * sizeof(typename std::decay_t<decltype(v)>::value_type); };
    return b(pos_) + b(vel_) + b(pred_) + b(pos_tmp_) + b(vel_tmp_) + b(pred_tmp_) + b(presence_) + b(presence_tmp_) +
           b(id_) + b(id_tmp_) + b(status_) + b(status_tmp_) + b(error_) + b(keys_) + b(order_) + b(offsets_) +
           b(fine_offsets_) + b(pairs_) + b(pair_count_) + b(wall_grad_) + walls_.bytes() + raw_copies_.bytes() +
           lists_.bytes() + exchange_.bytes() + refresh_.bytes();
  }

  void step(double until) override {
    // Presence on every step that may reach `until`: a step is at most
    // max_dt, stretched by up to kLandSlack to land on it (ChooseFlowStep).
    const bool presence_now =
        presence_mode_ == PresenceMode::EveryStep ||
        (presence_mode_ == PresenceMode::AtUntil && t_ + ChooseFlowStep::kLandSlack * max_dt_ >= until - 1e-12);
    clock_.start();
    obstacles_.view.time = float(t_);
    FlowControl* control = raw(control_);
    parallel_for("pbf_choose_step", 1,
                 ChooseFlowStep{cfl_ * prm_.spacing, double(pbf_.speed_floor), max_dt_, double(pbf_.max_dt_depth), min_dt_,
                               std::max(until - t_, 0.0), control, double(pbf_.step_error),
                               double(pbf_.step_error_flow), double(pbf_.flow_speed)});
    walls_.move(obstacles_.view, control);  // to the step's end, where the corrections meet them
    parallel_for("pbf_predict", n_, Predict{prm_, control, raw(pos_), raw(vel_), raw(pred_), obstacles_.view,
                                            pbf_.wall_margin, step_grid_, predict_keys() ? raw(keys_) : nullptr});
    if (transport_) {
      exchange(pred_);
      clock_.end_of("exchange");
    }
    sort_by(pred_, true);
    if (transport_) refresh_.build(bounds_, raw(pred_), status_, id_, n_, *transport_);
    grid_current_ = false;
    build_masks();
    clock_.end_of("grid");
    const int iterations = solve();
    clock_.end_of("pairs");
    finish(presence_now);
    reduce_stats();
    control_read_.start(control);
    clock_.end_of("integrate");
    clock_.finish();
    const FlowControl& c = control_read_.value();
    // The state is checked once the step's kernels have run: a bad step is
    // reported, not continued from.
    if (c.outcome == kStepBelowFloor)
      throw SimulationError(describe_flow_dt_floor(c.limits, min_dt_, cfl_, t_, steps_));
    check_flow_state("PBF", "lower sph.cfl or raise pbf.iterations", c.stats, steps_, t_, pos_, vel_, id_);
    limits_ = c.limits;
    times_ = {clock_.ms("grid"), clock_.ms("pairs"), clock_.ms("integrate")};
    times_.exchange = transport_ ? clock_.ms("exchange") : 0.0;
    solve_.iterations = iterations;
    solve_.density_error_mean = c.stats.count > 0 ? c.stats.error_sum / c.stats.count : 0.0;
    solve_.density_error_max = c.stats.error_max;
    solve_.converged = pbf_.tolerance <= 0 || solve_.density_error_mean <= pbf_.tolerance;
    t_ += limits_.dt;
    ++steps_;
  }

  // A decomposed run: this rank's slab, whose halo must hold the PBF
  // support (see above). The exchange at once, placed at x (each step's
  // places them at x* again): the grid then holds the ghosts, as between
  // steps, and the transport has carried its first records before a step is
  // timed (NCCL connects its peers on the first, about a second).
  void set_slab(const SlabBounds& bounds) override {
    if (!transport_) throw std::logic_error("PBF: set_slab without a transport (SolverInput::transport)");
    if (bounds.halo_free < pbf_.kernel.s) throw std::logic_error("PBF: a halo narrower than its support");
    bounds_ = bounds;
    exchange(pos_);
    sort_by(pos_, false);
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

 private:
  PairMask pairs() { return {raw(pairs_), raw(pair_count_), n_, mask_words_}; }
  // Whether Predict writes the step sort's keys with the prediction: not
  // where an exchange moves the particles between the two.
  bool predict_keys() const { return transport_ == nullptr; }
  // The ghosts of a decomposed run take their owners' values of `values`.
  void refresh(Vector<Float4>& values) {
    if (transport_) refresh_.refresh(values, *transport_);
  }
  FlowArrays arrays() {
    return {pos_, vel_, pred_, pos_tmp_, vel_tmp_, pred_tmp_, id_, id_tmp_, status_, status_tmp_, presence_, presence_tmp_};
  }

  // Sorts every particle array by the cell of `by` (pos_ or pred_), on the
  // step's grid (`step`) or the scene's (the view's), and drops the
  // particles outside the grid (an open top only) and those the step's
  // exchange sent away. The step's sort (at x*, keyed by Predict unless an
  // exchange came between) carries neither velocities nor presence: the
  // finishing pass writes every particle's velocity, and its presence or
  // none (presence_valid_), and nothing reads either before it.
  void sort_by(const Vector<Float4>& by, bool step) {
    static constexpr const char* kNames[2] = {"pbf_keys", "pbf_gather"};
    const FlowSortCarry carry = step ? FlowSortCarry{false, false, predict_keys()} : FlowSortCarry{presence_valid_};
    const FlowSort r = sort_flow_particles(kNames, step ? step_grid_ : grid_, prm_.open_top, n_, by, carry, arrays(),
                                           keys_, order_, fine_offsets_, step ? nullptr : &offsets_, gone_);
    gone_ = false;
    removed_ += r.dropped_owned;
    ghosts_ -= r.dropped_ghosts;
    n_ = r.active;
    grid_current_ = !step;
  }

  // The exchange (exchange_impl.inl) after the prediction, placed at x*
  // (`place` pred_; set_slab: pos_): the particles this rank holds for the
  // step, unsorted (sort_by follows).
  void exchange(const Vector<Float4>& place) {
    const ConstParticleArrays s{raw(pos_), raw(vel_), raw(pred_), raw(id_), raw(status_), nullptr};
    const ExchangeResult r = exchange_particles(exchange_, bounds_, grid_, nullptr, *transport_, s, raw(place),
                                                raw(status_), n_, [&](uint32_t n) {
                                                  fit(n);
                                                  return ParticleArrays{raw(pos_), raw(vel_), raw(pred_), raw(id_),
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
    for (auto* v : {&pos_, &vel_, &pred_, &pos_tmp_, &vel_tmp_, &pred_tmp_}) grow_to(*v, n);
    for (auto* v : {&id_, &id_tmp_, &keys_, &order_, &pair_count_}) grow_to(*v, n);
    for (auto* v : {&status_, &status_tmp_}) grow_to(*v, n);
    grow_to(error_, n);
    if (walls_.size()) grow_to(wall_grad_, n);
    grow_to(pairs_, size_t(mask_words_) * n);
    if (presence_mode_ != PresenceMode::Off) {
      grow_to(presence_, 6 * size_t(n));
      grow_to(presence_tmp_, 6 * size_t(n));
    }
  }

  // The pair masks at the predicted positions, searched within the support
  // only (the grid's cells are wider: pbf_support_cells in setup.cpp), and
  // the launches' particles for the step: the iterations move a particle by
  // at most max_correction each (and a stop's offset, obstacles.h, taken
  // twice for slack), so its class holds within that margin (none without
  // the limit).
  void build_masks() {
    BuildPairMask b{step_grid_, raw(fine_offsets_), raw(pred_), raw(pred_), pbf_.kernel.s * pbf_.kernel.s, true, pairs()};
    b.search_radius = pbf_.kernel.s;  // the cell size, to rounding
    parallel_for("pbf_pair_masks", n_, b);
    const float margin = pbf_.max_correction > 0.0f
                             ? float(pbf_.iterations) * (pbf_.max_correction + 2.0f * obstacles_.view.offset)
                             : pbf_.kernel.s;
    // A decomposed run's passes skip the ghosts and start with what the
    // peers read where the ghosts are a large enough share of the particles
    // (SlabBounds::overlap_above; iteration_pass).
    if (transport_ && double(ghosts_) >= double(bounds_.overlap_above) * double(n_))
      lists_.classify(n_, prm_, pbf_.kernel.s, margin, walls_.view(), pairs(), raw(pred_), raw(status_),
                      refresh_.peer_bits(), refresh_.listed_bound(), ghosts_);
    else
      lists_.classify(n_, prm_, pbf_.kernel.s, margin, walls_.view(), pairs(), raw(pred_));
  }

  static constexpr const char* kLambdaNames[3] = {"pbf_lambda", "pbf_lambda_walls",
                                                  "pbf_lambda_direct"};
  static constexpr const char* kCorrectNames[3] = {"pbf_correct", "pbf_correct_walls",
                                                   "pbf_correct_direct"};

  // Without obstacles the last correction is finish()'s (CorrectFinish):
  // the stop at an obstacle must come between a correction and the velocity.
  bool fused_finish() const { return obstacles_.view.count == 0; }

  // The constraint iterations; returns how many corrections were applied
  // (with fused_finish(), counting the one finish() applies).
  int solve() {
    const bool stop = !fused_finish();  // the obstacles' stop after each Correct
    bool may_end = false;  // whether pbf.tolerance may end this step's iterations (read with the first error)
    for (int k = 0; k < pbf_.iterations; ++k) {
      const float rest_weight = pbf_.rest_weights > 0 ? pbf_.rest_weight[k % pbf_.rest_weights] : 1.0f;
      iteration_pass<Lambda>(kLambdaNames, pred_tmp_, false, prm_, pbf_, step_grid_, raw(fine_offsets_), pairs(),
                             raw(pred_), raw(pred_tmp_), raw(error_), walls_.view(), raw(wall_grad_), raw(control_),
                             rest_weight);
      pred_.swap(pred_tmp_);
      // Ending early needs the error on the host: one read per iteration,
      // and on the first the step's control. Only on a step of a flowing
      // liquid that the error-sized limit does not hold: at rest the
      // iterations are the rest weights' schedule (pbf_weights.h), which
      // holds a pool still only when run to its end, and a step held by the
      // error-sized limit is one sized to the compression its iterations
      // leave (docs/validation.md, "Iterations ended by the tolerance").
      if (k == 0 && pbf_.tolerance > 0) {
        const FlowControl c = read_one(control_, 0);
        may_end = c.flowing && c.limits.bound != kBoundSolver;
      }
      const bool converged = may_end && mean_over_run(error_, n_, ghosts_, status_, transport_) <= pbf_.tolerance;
      if (fused_finish() && (converged || k + 1 == pbf_.iterations)) return k + 1;
      if (converged) return k;
      iteration_pass<Correct>(kCorrectNames, pred_tmp_, stop, prm_, pbf_, step_grid_, raw(fine_offsets_), pairs(),
                              raw(pred_), raw(pred_tmp_), walls_.view(), raw(wall_grad_));
      pred_.swap(pred_tmp_);
    }
    return pbf_.iterations;
  }

  // One pass of the iterations into `out` (from pred_), the corrections
  // stopped at the obstacles where `stop`; a decomposed run's ghosts then take
  // their owners' values. Where the lists are grouped (build_masks: ghosts
  // are SlabBounds::overlap_above of the particles or more) the particles
  // that peers hold ghosts of are computed on the lists' side stream and
  // their values sent from there, while the rest of the rank's own particles
  // are computed on the default stream; the ghosts are skipped (the refresh
  // brings their values). With a stop (a pass over every particle after the
  // corrections) the refresh follows it instead.
  template <template <int> class Pass, class... Args>
  void iteration_pass(const char* const (&names)[3], Vector<Float4>& out, bool stop, Args... args) {
    const bool mesh = walls_.size() > 0;
    if (!lists_.grouped()) {
      mirror_pass_launches<Pass>(names, lists_, mesh, args...);
      if (stop) stop_corrections(out);
      refresh(out);
      return;
    }
    // The default stream's large launch is queued first, so that the host's
    // transport calls do not hold it back.
    SideStream& side = lists_.side();
    side.fork();
    mirror_group_launch<Pass>(names, lists_, mesh, kGroupListed, &side, args...);
    mirror_group_launch<Pass>(names, lists_, mesh, kGroupRest, nullptr, args...);
    mirror_direct_launch<Pass>(names, lists_, &side, args...);
    if (!stop) refresh_.refresh_beside(out, *transport_, side);
    side.join();
    if (stop) {
      stop_corrections(out);
      refresh(out);
    }
  }

  // The corrections from pred_ to `out` stopped at the obstacles (pbf.h).
  void stop_corrections(Vector<Float4>& out) {
    parallel_for("pbf_stop", n_, StopCorrection{prm_, obstacles_.view, raw(control_), raw(pred_), raw(out), pbf_.wall_margin});
  }

  void finish(bool presence) {
    presence_valid_ = presence;
    if (presence) finish_launches<true>();
    else finish_launches<false>();
    pos_.swap(pos_tmp_);
    vel_.swap(vel_tmp_);
    if (pbf_.vorticity > 0) confine_vorticity();
  }

  // Vorticity confinement (pbf.h): omega into vel_tmp_ (free after the swap),
  // then the velocities.
  void confine_vorticity() {
    const FlowControl* control = raw(control_);
    refresh(vel_);  // a ghost's XSPH smoothing lacked the neighbours beyond the halo
    parallel_for("pbf_vorticity", n_,
                 Vorticity<false>{pbf_, step_grid_, raw(fine_offsets_), pairs(), raw(pos_), raw(vel_), raw(vel_tmp_)});
    parallel_for("pbf_vorticity_direct", n_,
                 Vorticity<true>{pbf_, step_grid_, raw(fine_offsets_), pairs(), raw(pos_), raw(vel_), raw(vel_tmp_)});
    refresh(vel_tmp_);
    parallel_for("pbf_confine", n_,
                 Confine<false>{pbf_, step_grid_, raw(fine_offsets_), pairs(), control, raw(pos_), raw(vel_tmp_), raw(vel_)});
    parallel_for("pbf_confine_direct", n_,
                 Confine<true>{pbf_, step_grid_, raw(fine_offsets_), pairs(), control, raw(pos_), raw(vel_tmp_), raw(vel_)});
  }

  // The finishing pass's launches (pbf.h, MirrorPass), with or without
  // presence: with the last correction where fused_finish(), else after it.
  static constexpr const char* kFinishNames[3] = {"pbf_finish", "pbf_finish_walls",
                                                  "pbf_finish_direct"};
  static constexpr const char* kCorrectFinishNames[3] = {"pbf_correct_finish", "pbf_correct_finish_walls",
                                                         "pbf_correct_finish_direct"};
  template <bool Presence>
  void finish_launches() {
    const FlowControl* control = raw(control_);
    float* presence = Presence ? raw(presence_) : nullptr;
    if (fused_finish()) {
      mirror_pass_launches<WithFlag<Presence, CorrectFinish>::template pass>(
          kCorrectFinishNames, lists_, false, prm_, pbf_, step_grid_, raw(fine_offsets_), pairs(), control, raw(pred_),
          raw(pos_), raw(pos_tmp_), raw(vel_tmp_), presence, n_);
      return;
    }
    mirror_pass_launches<WithFlag<Presence, Finish>::template pass>(
        kFinishNames, lists_, walls_.size() > 0, prm_, pbf_, step_grid_, raw(fine_offsets_), pairs(), control,
        raw(pred_), raw(pos_), raw(pos_tmp_), raw(vel_tmp_), raw(error_), presence, n_, walls_.view());
  }

  // Speed, density error and finiteness of the current state, into the
  // control that the next step's size is chosen from.
  void reduce_stats() { reduce_flow_stats(n_, pos_, vel_, error_, status_, id_, transport_, &raw(control_)->stats); }


  SphParams prm_;
  PbfParams pbf_;
  GridGeom grid_;       // the scene's (the view's)
  GridGeom step_grid_;  // the step's: cells of one support
  double cfl_, min_dt_, max_dt_;
  uint32_t n_;
  ObstacleSet obstacles_;  // meshes the particles' paths stop at (obstacles.h)
  WallParticles walls_;    // the obstacles' (mesh_walls.h)
  PresenceMode presence_mode_ = PresenceMode::Off;
  bool presence_valid_ = false;
  bool grid_current_ = false;  // sorted on grid_ by pos_ (else on step_grid_ by pred_, as at the step's start)
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
  // pos_: x, density; vel_: v; pred_: x*, lambda during the iterations.
  Vector<Float4> pos_, vel_, pred_, pos_tmp_, vel_tmp_, pred_tmp_;
  Vector<float> presence_, presence_tmp_, error_;
  Vector<Float4> wall_grad_;  // per particle near the obstacles' walls (pbf.h, Lambda)
  Vector<uint32_t> id_, id_tmp_, keys_, order_, offsets_, fine_offsets_;
  Vector<uint8_t> status_, status_tmp_;
  uint32_t mask_words_ = 0;
  Vector<PairWord> pairs_;
  Vector<uint32_t> pair_count_;
  LaunchLists lists_;  // the neighbour passes' particles per launch (flow_solver.inl), with the masks
  // A decomposed run (set_slab): the transport, the slabs (halo: the PBF
  // support), the exchange's buffers, the ghosts' refresh lists, and how
  // many of the n_ particles are ghosts.
  ParticleTransport* transport_ = nullptr;
  SlabBounds bounds_;
  ExchangeBuffers exchange_;
  GhostRefresh refresh_;
  uint32_t ghosts_ = 0;
  bool gone_ = false;  // the arrays hold particles the step's exchange sent away
};
