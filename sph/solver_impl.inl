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

#include "nsearch/sort.inl"
#include "particle_copies.inl"
#include "exchange_impl.inl"
#include "wall_particles.inl"

// The particle data into the new sorted order, one kernel for all of it
// (one read of the order): out[i] = in[order[i]] for the first n_new sorted
// particles. Presence and the covariance sums, when there are any, [6][n_old]
// -> [6][n_new] and [3][n_old] -> [3][n_new]; the velocities unless in.vel
// is null.
struct GatherParticles {
  const uint32_t* order;
  ConstParticleArrays in;  // presence null: none to carry
  uint32_t n_old;
  ParticleArrays out;
  uint32_t n_new;
  SPHRAY_HD void operator()(uint32_t i) const {
    const uint32_t j = order[i];
    out.pos[i] = in.pos[j];
    if (in.vel) out.vel[i] = in.vel[j];
    out.flow[i] = in.flow[j];
    out.id[i] = in.id[j];
    out.status[i] = in.status[j];
    if (in.presence)
      for (uint32_t k = 0; k < 6; ++k) out.presence[k * n_new + i] = in.presence[k * n_old + j];
    if (in.covariance)
      for (uint32_t k = 0; k < 3; ++k) out.covariance[k * n_new + i] = in.covariance[k * n_old + j];
  }
};

// Cell keys after an exchange: a particle sent away is keyed outside the
// grid, so that the sort puts it last and the build drops it.
struct KeyOfStaying {
  GridGeom grid;
  const Float4* pos;
  const uint8_t* status;
  uint32_t* keys;
  SPHRAY_HD void operator()(uint32_t i) const {
    keys[i] = status[i] == kStatusGone ? grid.num_fine_cells() : grid.fine_key_of(xyz(pos[i]));
  }
};

// The particles' ids: in.fluid_id (a resumed run's, a rank's share of a
// decomposed run's), or their indices.
inline std::vector<uint32_t> initial_ids(const SolverInput& in, const char* solver) {
  const size_t n = in.fluid_pos_rho.size();
  if (!in.fluid_id.empty() && in.fluid_id.size() != n)
    throw std::invalid_argument(std::string(solver) + ": fluid_id and fluid_pos_rho differ in length");
  std::vector<uint32_t> ids(in.fluid_id);
  if (ids.empty()) {
    ids.resize(n);
    for (size_t i = 0; i < n; ++i) ids[i] = uint32_t(i);
  }
  return ids;
}

class SolverImpl final : public Solver {
 public:
  explicit SolverImpl(const SolverInput& in)
      : prm_(in.params), grid_(in.grid), cfl_(in.cfl), min_dt_(in.min_dt), max_dt_(in.max_dt),
        n_(uint32_t(in.fluid_pos_rho.size())), covariance_radius_(in.covariance_radius),
        covariance_mirror_walls_(in.covariance_mirror_walls),
        obstacles_(make_obstacle_set(kBackend, in.obstacles, in.params.spacing)), walls_(in, in.grid) {
    if (covariance_radius_ > prm_.kernel.support())
      throw std::invalid_argument("WCSPH: the covariance radius exceeds the kernel's support");
    const size_t n = n_, cells = size_t(grid_.num_cells()) + 1, slabs = size_t(grid_.num_fine_cells()) + 1;
    t_ = in.start_time;
    steps_ = in.start_step;
    transport_ = in.transport;
    moving_walls_ = !in.boundary_obstacle.empty();
    upload(pos_, in.fluid_pos_rho);
    upload(vel_, in.fluid_vel);
    flow_ = vel_;  // u = v until there is an acceleration to predict with
    upload(id_, initial_ids(in, "WCSPH"));
    status_.assign(n, uint8_t(kStatusOk));
    offsets_.resize(cells); fine_offsets_.resize(slabs);
    mask_words_ = in.pair_mask_words >= 0 ? uint32_t(in.pair_mask_words)
                                          : pair_mask_capacity(double(prm_.kernel.support()) / double(prm_.spacing));
    fit(n_);
    parallel_for("pressure_term", n_, PressureTermOf{prm_, raw(pos_), raw(flow_)});
    set_presence(in.presence);

    wall_.resize(walls_.size());
    fluid_near_.resize(grid_.num_cells());
    build_grid();
  }

  Backend backend() const override { return kBackend; }
  SolverKind kind() const override { return SolverKind::Wcsph; }
  double time() const override { return t_; }
  uint64_t steps() const override { return steps_; }
  size_t num_fluid() const override { return n_ - ghosts_; }
  size_t num_removed() const override { return removed_; }
  uint64_t num_clamped() const override {
    // Clamps of the last integration are not yet in clamped_total_.
    return clamped_total_ + uint64_t(thrust::count(policy(), status_.begin(), status_.begin() + n_, uint8_t(kStatusClamped)));
  }
  const StepLimits& last_limits() const override { return limits_; }
  const StageTimes& last_stage_times() const override { return times_; }
  bool has_presence() const override { return presence_valid_; }
  PresenceMode presence_mode() const override { return presence_mode_; }
  void set_presence(PresenceMode mode) override {
    presence_mode_ = mode;
    fit_presence(n_);
  }
  ParticleView view() const override {
    ParticleView v{kBackend, n_, raw(pos_), raw(offsets_), presence_valid_ ? raw(presence_) : nullptr, grid_,
                   raw(fine_offsets_)};
    if (covariance_valid()) {
      v.covariance = raw(covariance_);
      v.covariance_radius = covariance_radius_;
      v.covariance_mirror_walls = covariance_mirror_walls_;
    }
    return v;
  }

  size_t device_bytes() const override {
    auto b = [](const auto& v) { return v.size() * sizeof(typename std::decay_t<decltype(v)>::value_type); };
    return b(pos_) + b(vel_) + b(flow_) + b(pos_tmp_) + b(vel_tmp_) + b(flow_tmp_) + b(accel_) + b(rate_grad_) + b(presence_) + b(presence_tmp_) + b(covariance_) + b(covariance_tmp_) + b(id_) +
           b(id_tmp_) + b(status_) + b(status_tmp_) + b(keys_) + b(order_) + b(offsets_) + b(fine_offsets_) + b(wall_) +
           b(fluid_pairs_) + b(boundary_pairs_) + b(fluid_pair_count_) + b(boundary_pair_count_) + b(fluid_near_) +
           walls_.bytes() + raw_copies_.bytes() + exchange_.bytes();
  }

  // Stage order: pairs (wall pressure, then one neighbour loop for the
  // acceleration, the density rate and presence), the step size from their
  // extremes, integrate (kick, density, drift), grid.
  void step(double until) override {
    // Presence is computed in the pair loop, before dt is known: on every
    // step that may reach `until` (dt can only be smaller than the bound).
    const bool presence_now = presence_mode_ == PresenceMode::EveryStep ||
                              (presence_mode_ == PresenceMode::AtUntil && t_ + dt_bound() >= until - 1e-12);
    obstacles_.view.time = float(t_);
    clock_.start();
    const int extras = !presence_now ? kPairPlain : covariance_radius_ > 0 ? kPairPresenceCovariance : kPairPresence;
    if (prm_.kernel.type == KernelType::WendlandC2) pairs<KernelType::WendlandC2>(extras);
    else pairs<KernelType::CubicSpline>(extras);
    presence_valid_ = presence_now;
    clock_.end_of("pairs");
    // The step's size is chosen on the device (integrate.h, ChooseStep), so
    // that nothing waits for the host between the reduction and the kick; the
    // host reads the decision once the step's work is done, and raises its
    // error then (a refused step moves no particle).
    StepControl* control = raw(control_);
    transform_reduce_into(n_, StepStatsOf{const_state(), pair_results()}, CombineStepStats(), kEmptyStepStats,
                          &control->stats);
    // A decomposed run: the extremes over all ranks, so that every rank takes one dt.
    if (transport_) transport_->max(&control->stats.max_speed2, 2);
    parallel_for("choose_step", 1,
                 ChooseStep{step_rule(), min_dt_, std::max(until - t_, 0.0), control, const_state(), pair_results()});
    parallel_for("advance", n_, Advance{prm_, control, state(), pair_results(), obstacles_.view});
    control_read_.start(control);
    clock_.end_of("integrate");
    if (transport_) {
      exchange();
      clock_.end_of("exchange");
    }
    build_grid(control);
    clock_.end_of("grid");
    clock_.finish();
    const StepControl& c = control_read_.value();
    if (c.outcome == kStepBadParticle) throw SimulationError(describe_bad_particle(c));
    if (c.outcome == kStepSupersonic) throw SimulationError(describe_supersonic(c), supersonic_elsewhere(c));
    clamped_total_ += c.stats.clamped;
    limits_ = c.limits;
    if (c.outcome == kStepBelowFloor) throw SimulationError(describe_dt_floor());
    times_ = {clock_.ms("grid"), clock_.ms("pairs"), clock_.ms("integrate")};
    times_.exchange = transport_ ? clock_.ms("exchange") : 0.0;
    t_ += limits_.dt;
    ++steps_;
  }

  void set_slab(const SlabBounds& bounds) override {
    if (!transport_) throw std::logic_error("WCSPH: set_slab without a transport (SolverInput::transport)");
    bounds_ = bounds;
    exchange();
    build_grid();
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

  // On CUDA the copies run behind the next steps (RawCopies): out.ready
  // waits for them.
  void download_raw(RawParticles& out, bool velocity, bool presence) const override {
    raw_copies_.take(out, pos_, vel_, id_, presence && presence_valid_ ? &presence_ : nullptr, n_, velocity);
  }

  std::vector<Vec3f> boundary_positions() const override { return walls_.positions(); }
  const float* device_pressure() override {
    if (pressure_out_.size() < n_) pressure_out_.resize(n_);
    parallel_for("tait_pressure", n_, TaitPressureOf{prm_, raw(pos_), raw(pressure_out_)});
    return raw(pressure_out_);
  }

 private:
  template <int E, bool Direct, KernelType K>
  Interaction<E, Direct, K> pair_stage() {
    const WallsIn walls{walls_.offsets(), walls_.pos(), raw(wall_), walls_.alpha(), walls_.vel()};
    const PairOut out{raw(accel_), raw(rate_grad_), E != kPairPlain ? raw(presence_) : nullptr,
                      E == kPairPresenceCovariance ? raw(covariance_) : nullptr,
                      covariance_radius_ > 0 ? 1.0f / covariance_radius_ : 0.0f,
                      covariance_mirror_walls_ ? covariance_radius_ : 0.0f};
    return {prm_, grid_, fluid_in(), walls, fluid_pairs(), boundary_pairs(), out, n_};
  }

  // The exchange after a step (exchange_impl.inl): the particles this rank
  // holds from now on, in the arrays, unsorted (build_grid follows).
  void exchange() {
    const ExchangeResult r =
        exchange_particles(exchange_, bounds_, grid_, moving_walls_ ? nullptr : walls_.near(), *transport_,
                           const_state(), raw(pos_), raw(status_), n_, [&](uint32_t n) {
                             fit(n, true);
                             return state();
                           });
    n_ = r.n;
    ghosts_ = r.ghosts;
    gone_ = true;  // build_grid drops them
  }

  // Grows every per-particle buffer to hold n particles (never shrinks: a
  // decomposed run's count changes a little every step; `spare`: a tenth more,
  // so that it rarely grows, as each growth copies the contents).
  void fit(uint32_t n, bool spare = false) {
    auto grow = [spare](auto& v, size_t size) {
      if (v.size() < size) v.resize(spare ? size + size / 10 : size);
    };
    for (auto* v : {&pos_, &vel_, &flow_, &pos_tmp_, &vel_tmp_, &flow_tmp_, &accel_, &rate_grad_}) grow(*v, n);
    for (auto* v : {&id_, &id_tmp_, &keys_, &order_, &fluid_pair_count_, &boundary_pair_count_}) grow(*v, n);
    grow(status_, n);
    grow(status_tmp_, n);
    grow(fluid_pairs_, size_t(mask_words_) * n);
    grow(boundary_pairs_, size_t(mask_words_) * n);
    fit_presence(n);
  }
  // Presence and the covariance sums: allocated once a mode other than Off asks for them.
  void fit_presence(uint32_t n) {
    if (presence_mode_ == PresenceMode::Off) return;
    if (presence_.size() < 6 * size_t(n)) {
      presence_.resize(6 * size_t(n));
      presence_tmp_.resize(6 * size_t(n));
    }
    if (covariance_radius_ > 0 && covariance_.size() < 3 * size_t(n)) {
      covariance_.resize(3 * size_t(n));
      covariance_tmp_.resize(3 * size_t(n));
    }
  }

  // The views of the particle arrays that the kernels take (particles.h).
  FluidIn fluid_in() const { return {raw(fine_offsets_), raw(pos_), raw(flow_)}; }
  ParticleArrays state() {
    return {raw(pos_), raw(vel_), raw(flow_), raw(id_), raw(status_), presence_valid_ ? raw(presence_) : nullptr,
            covariance_valid() ? raw(covariance_) : nullptr};
  }
  ConstParticleArrays const_state() const {
    return {raw(pos_), raw(vel_), raw(flow_), raw(id_), raw(status_), presence_valid_ ? raw(presence_) : nullptr,
            covariance_valid() ? raw(covariance_) : nullptr};
  }
  // The covariance sums are summed with presence where the solver has a radius for them.
  bool covariance_valid() const { return presence_valid_ && covariance_radius_ > 0; }
  PairIn pair_results() const { return {raw(accel_), raw(rate_grad_)}; }

  // The pairs stage: the wall pressure, then the pair loop. The kernel type K
  // is a template parameter of both loops (kernel.h, W_for and dW_over_r_for).
  template <KernelType K>
  void pairs(int extras) {
    parallel_for("wall_pressure", walls_.size(),
                 WallPressure<K>{prm_, grid_, fluid_in(), raw(fluid_near_), walls_.pos(), raw(wall_)});
    if (extras == kPairPresenceCovariance) pair_launches<kPairPresenceCovariance, K>();
    else if (extras == kPairPresence) pair_launches<kPairPresence, K>();
    else pair_launches<kPairPlain, K>();
  }

  // The pair loop is two launches: the pair masks, then the direct loop for
  // the particles whose masks overflowed (nsearch/pair_masks.h; usually none).
  template <int E, KernelType K>
  void pair_launches() {
    parallel_for("pair_loop", n_, pair_stage<E, false, K>());
    parallel_for("pair_loop_direct", n_, pair_stage<E, true, K>());
  }

  PairMask fluid_pairs() { return {raw(fluid_pairs_), raw(fluid_pair_count_), n_, mask_words_}; }
  PairMask boundary_pairs() { return {raw(boundary_pairs_), raw(boundary_pair_count_), n_, mask_words_}; }

  void build_grid(const StepControl* control = nullptr) {
    if (control) walls_.move(obstacles_.view, control);
    if (gone_) parallel_for("fluid_keys", n_, KeyOfStaying{grid_, raw(pos_), raw(status_), raw(keys_)});
    else parallel_for("fluid_keys", n_, KeyOf<Float4>{grid_, raw(pos_), raw(keys_)});
    sort_and_offsets(grid_, n_, keys_, order_, fine_offsets_, &offsets_);
    // Particles outside the grid (only possible through an open top: Advance
    // keeps them inside a closed tank, whose grid holds its walls besides)
    // sorted last: drop them. Reading their count waits for the sort, so a
    // closed tank does not.
    // So are the particles an exchange sent away (kStatusGone: their keys are
    // outside the grid).
    const uint32_t active = prm_.open_top || gone_ ? read_one(offsets_, grid_.num_cells()) : n_;
    // The run's own particles among those dropped are removed; another rank's
    // ghosts and those sent away are not.
    uint32_t dropped_owned = n_ - active, dropped_ghosts = 0;
    if (active < n_ && transport_) {
      const auto dropped = thrust::make_permutation_iterator(status_.begin(), order_.begin() + active);
      dropped_ghosts = uint32_t(thrust::count(policy(), dropped, dropped + (n_ - active), uint8_t(kStatusGhost)));
      const uint32_t sent = uint32_t(thrust::count(policy(), dropped, dropped + (n_ - active), uint8_t(kStatusGone)));
      dropped_owned -= dropped_ghosts + sent;
    }
    gone_ = false;
    const ParticleArrays out{raw(pos_tmp_), raw(vel_tmp_), raw(flow_tmp_), raw(id_tmp_), raw(status_tmp_),
                             raw(presence_tmp_), raw(covariance_tmp_)};
    parallel_for("gather_particles", active, GatherParticles{raw(order_), const_state(), n_, out, active});
    pos_.swap(pos_tmp_);
    vel_.swap(vel_tmp_);
    flow_.swap(flow_tmp_);
    id_.swap(id_tmp_);
    status_.swap(status_tmp_);
    if (presence_valid_) presence_.swap(presence_tmp_);
    if (covariance_valid()) covariance_.swap(covariance_tmp_);
    removed_ += dropped_owned;
    ghosts_ -= dropped_ghosts;
    n_ = active;
    parallel_for("fluid_cells_near", grid_.num_cells(), CellsNear{grid_, raw(fine_offsets_), raw(fluid_near_)});
    // The pair masks of the next step's pair loop (nsearch/pair_masks.h), at these positions.
    const float support2 = prm_.kernel.support() * prm_.kernel.support();
    parallel_for("fluid_pair_masks", n_, BuildPairMask{grid_, raw(fine_offsets_), raw(pos_), raw(pos_), support2, true, fluid_pairs()});
    parallel_for("wall_pair_masks", n_, BuildPairMask{grid_, walls_.offsets(), walls_.pos(), raw(pos_), support2, false,
                                   boundary_pairs(), walls_.near()});
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

  // Over several ranks the largest speed is every rank's, the particle this
  // rank's fastest: on a rank whose own fastest is slower (beyond float
  // round-off) the particle that outran c0 is another rank's.
  bool supersonic_elsewhere(const StepControl& c) const {
    return transport_ && double(length(xyz(c.bad_vel))) < (1.0 - 1e-5) * c.limits.max_speed;
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
  float covariance_radius_;  // [m] SolverInput::covariance_radius
  bool covariance_mirror_walls_;  // SolverInput::covariance_mirror_walls
  // A decomposed run (set_slab): the transport, the slabs, the exchange's
  // buffers, and how many of the n_ particles are other ranks' ghosts.
  ParticleTransport* transport_ = nullptr;
  SlabBounds bounds_;
  ExchangeBuffers exchange_;
  uint32_t ghosts_ = 0;
  bool gone_ = false;  // the arrays hold particles the last exchange sent away
  // Obstacles move: the walls' cell flags of the last grid may miss where
  // they are now, so the exchange takes the full halo everywhere.
  bool moving_walls_ = false;
  PresenceMode presence_mode_ = PresenceMode::Off;
  bool presence_valid_ = false;
  double t_ = 0;
  uint64_t steps_ = 0;
  size_t removed_ = 0;
  uint64_t clamped_total_ = 0;
  ObstacleSet obstacles_;
  WallParticles walls_;  // the tank's and the obstacles' (boundary.h)
  StepLimits limits_;
  StageTimes times_;
  StageClock clock_;
  // The step's decision on the device (ChooseStep) and its copy for the host.
  Vector<StepControl> control_ = Vector<StepControl>(1);
  ReadBack<StepControl> control_read_;
  mutable RawCopies raw_copies_;  // download_raw's staging buffers and copies

  // vel_: the exact velocity; flow_: what the pair loop reads of a neighbour,
  // u (the predicted kicked velocity) and p / rho^2 (integrate.h).
  Vector<Float4> pos_, vel_, flow_, pos_tmp_, vel_tmp_, flow_tmp_, accel_, rate_grad_;
  Vector<float> presence_, presence_tmp_;
  Vector<Float4> covariance_, covariance_tmp_;  // [3][n] (sph/covariance.h), with presence
  Vector<float> pressure_out_;  // device_pressure
  Vector<WallState> wall_;
  // offsets_: coarse cell table (view(), the field builder, the raycaster);
  // fine_offsets_: slab table of the neighbour loops (grid.h).
  Vector<uint32_t> id_, id_tmp_, keys_, order_, offsets_, fine_offsets_;
  // Pair masks of every fluid particle against the fluid and the walls (nsearch/pair_masks.h).
  uint32_t mask_words_ = 0;
  Vector<PairWord> fluid_pairs_, boundary_pairs_;
  Vector<uint32_t> fluid_pair_count_, boundary_pair_count_;
  Vector<uint8_t> status_, status_tmp_;
  // Per grid cell: whether fluid (updated with the grid) lies in the 27
  // cells around it (CellsNear, grid.h; the walls' flags: walls_.near()).
  Vector<uint8_t> fluid_near_;
};
