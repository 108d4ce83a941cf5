#include "slab_solver.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "transport.h"

namespace sphray {

namespace {

// A particle as rank 0 gathers it for the outputs.
struct Owned {
  uint32_t id;
  float pos[3], vel[3], density;
};


class SlabSolver final : public Solver {
 public:
  SlabSolver(std::unique_ptr<ParticleTransport> transport, Comm& comm, SlabPlan plan,
             const SlabOptions& opt, SolverInput frame_in, SolverMaker make)
      : transport_(std::move(transport)), comm_(comm), plan_(std::move(plan)), opt_(opt),
        frame_in_(std::move(frame_in)), make_(std::move(make)) {}

  // The inner solver holds this rank's particles; the first exchange gives it its ghosts.
  void start(std::unique_ptr<Solver> inner) {
    inner_ = std::move(inner);
    inner_->set_slab(bounds());
    sum_totals();
  }

  Backend backend() const override { return inner_->backend(); }
  SolverKind kind() const override { return inner_->kind(); }
  double time() const override { return inner_->time(); }
  uint64_t steps() const override { return inner_->steps(); }
  size_t num_fluid() const override { return size_t(totals_[0]); }
  size_t num_removed() const override { return size_t(totals_[1]); }
  uint64_t num_clamped() const override { return uint64_t(totals_[2]); }
  // The inner solver's, but for the fastest particle: its step statistics
  // reduce the largest speed over all ranks, and the particle that has it
  // may be another rank's (StepLimits::fastest_id).
  const StepLimits& last_limits() const override { return limits_; }
  const StageTimes& last_stage_times() const override { return inner_->last_stage_times(); }
  // The iterations (the same on every rank) and the density error over all ranks.
  SolveStats last_solve() const override { return inner_->last_solve(); }
  void set_presence(PresenceMode mode) override { inner_->set_presence(mode); }
  PresenceMode presence_mode() const override { return inner_->presence_mode(); }
  bool has_presence() const override { return false; }  // the exchange reorders it (cmd_run refuses what needs it)
  // Rank 0's grid of the gathered particles (SlabOptions::frame_view), else
  // this rank's own particles and ghosts.
  ParticleView view() const override { return frame_ ? frame_->view() : inner_->view(); }
  size_t device_bytes() const override { return inner_->device_bytes(); }
  std::vector<Vec3f> boundary_positions() const override { return inner_->boundary_positions(); }

  void step(double until) override {
    // A step refused by its guards ends after all of the step's collective
    // calls (the exchange included): the ranks then agree on it. Any other
    // error may leave the others inside one of them: it ends every rank
    // (apps/main.cpp, MPI_Abort).
    // The rank that reports is the first to fail for a particle of its own
    // (SimulationError::elsewhere), else the first to fail.
    std::string error;
    const int none = 2 * comm_.size();
    int failed = none;
    try {
      inner_->step(until);
    } catch (const SimulationError& e) {
      error = e.what();
      failed = e.elsewhere ? comm_.size() + comm_.rank() : comm_.rank();
    }
    comm_.min(&failed, 1);  // every rank learns whether one failed, and which reports
    if (failed < none) {
      failed %= comm_.size();
      comm_.broadcast(error, failed);
      throw RanksStopped("rank " + std::to_string(failed) + " of " + std::to_string(comm_.size()) + ": " + error);
    }
    limits_ = inner_->last_limits();
    limits_.fastest_id = kNoBadParticle;
    sum_totals();
    if (opt_.rebalance_every > 0 && steps() % uint64_t(opt_.rebalance_every) == 0) rebalance();
  }

  // This rank's own particles are kept where every rank reads them
  // (SlabOptions::keep_owned, download_owned); where an output needs them
  // all (SlabOptions::gather_to_root), rank 0 receives every rank's: packed
  // into one buffer sized once, unpacked into arrays sized once (unpacking
  // with per-particle growth took 13-14 ms of a 1M frame on rank 0).
  void gather_frame() override {
    const HostParticles h = inner_->download();
    const size_t n = h.id.size();
    if (opt_.keep_owned) {
      owned_.id.clear();
      owned_.pos.clear();
      owned_.vel.clear();
      owned_.id.reserve(n), owned_.pos.reserve(n), owned_.vel.reserve(n);
      for (size_t i = 0; i < n; ++i) {
        if (h.status[i] == kStatusGhost) continue;
        owned_.id.push_back(h.id[i]);
        owned_.pos.push_back({h.pos[i].x, h.pos[i].y, h.pos[i].z, h.density[i]});
        owned_.vel.push_back({h.vel[i].x, h.vel[i].y, h.vel[i].z, 0.0f});
      }
      owned_step_ = steps();
    }
    if (!opt_.gather_to_root) return;
    size_t owned = 0;
    for (size_t i = 0; i < n; ++i) owned += h.status[i] != kStatusGhost;
    std::vector<char> mine(owned * sizeof(Owned));
    char* at = mine.data();
    for (size_t i = 0; i < n; ++i) {
      if (h.status[i] == kStatusGhost) continue;
      const Owned o{h.id[i], {h.pos[i].x, h.pos[i].y, h.pos[i].z}, {h.vel[i].x, h.vel[i].y, h.vel[i].z}, h.density[i]};
      std::memcpy(at, &o, sizeof(Owned));
      at += sizeof(Owned);
    }
    const std::vector<std::vector<char>> all = comm_.gather(mine);
    size_t total = 0;
    for (const auto& buf : all) total += buf.size() / sizeof(Owned);
    gathered_.id.resize(total);
    gathered_.pos.resize(total);
    gathered_.vel.resize(total);
    gathered_.density.resize(total);
    size_t k = 0;
    for (const auto& buf : all)
      for (size_t b = 0; b + sizeof(Owned) <= buf.size(); b += sizeof(Owned), ++k) {
        Owned o;
        std::memcpy(&o, buf.data() + b, sizeof(Owned));
        gathered_.id[k] = o.id;
        gathered_.pos[k] = {o.pos[0], o.pos[1], o.pos[2]};
        gathered_.vel[k] = {o.vel[0], o.vel[1], o.vel[2]};
        gathered_.density[k] = o.density;
      }
    gathered_step_ = steps();
    if (opt_.frame_view && comm_.rank() == 0) {
      SolverInput in = frame_in_;
      in.fluid_pos_rho.resize(gathered_.id.size());
      in.fluid_vel.resize(gathered_.id.size());
      for (size_t i = 0; i < gathered_.id.size(); ++i) {
        const Vec3f p = gathered_.pos[i], v = gathered_.vel[i];
        in.fluid_pos_rho[i] = {p.x, p.y, p.z, gathered_.density[i]};
        in.fluid_vel[i] = {v.x, v.y, v.z, 0.0f};
      }
      in.fluid_id = gathered_.id;
      in.start_time = time();
      in.start_step = steps();
      frame_.reset();  // its buffers first
      frame_ = make_(in);  // sorts them into the grid
    }
  }

  HostParticles download() const override {
    check_gathered();
    return gathered_;
  }

  // The metrics row's sums over the gathered particles, without the copy
  // download() makes.
  FlowSums flow_sums() const override {
    check_gathered();
    return flow_sums_of(gathered_);
  }

  void download_owned(RawParticles& out, bool velocity) const override {
    if (!opt_.keep_owned || owned_step_ != steps())
      throw std::logic_error("a decomposed run's own particles are read at output frames only, where kept "
                             "(SlabOptions::keep_owned)");
    out.pos.assign(owned_.pos.begin(), owned_.pos.end());
    out.id.assign(owned_.id.begin(), owned_.id.end());
    if (velocity) out.vel.assign(owned_.vel.begin(), owned_.vel.end());
    else out.vel.clear();
    out.presence.clear();
    out.ready = {};
  }

  void download_raw(RawParticles& out, bool velocity, bool /*presence*/) const override {
    check_gathered();
    const size_t n = gathered_.id.size();
    out.pos.resize(n);
    out.id.resize(n);
    out.vel.resize(velocity ? n : 0);
    out.presence.clear();
    for (size_t i = 0; i < n; ++i) {
      const Vec3f p = gathered_.pos[i], v = gathered_.vel[i];
      out.pos[i] = {p.x, p.y, p.z, gathered_.density[i]};
      out.id[i] = gathered_.id[i];
      if (velocity) out.vel[i] = {v.x, v.y, v.z, 0.0f};
    }
    out.ready = {};
  }

 private:
  void check_gathered() const {
    if (gathered_step_ != steps())
      throw std::logic_error("a decomposed run's particles are read at output frames only (gather_frame)");
  }

  // The run's counts over all ranks.
  void sum_totals() {
    totals_ = {double(inner_->num_fluid()), double(inner_->num_removed()), double(inner_->num_clamped())};
    comm_.sum(totals_.data(), 3);
  }

  // Moves the cuts toward the quantiles of the particles along the axis when
  // the ranks' counts differ by more than opt_.rebalance_above; each cut by
  // less than half the least slab width, so that every particle's new owner
  // is its holder or a neighbour (the exchange's reach, sph/exchange.h).
  void rebalance() {
    const int ranks = comm_.size();
    if (ranks < 2) return;
    std::vector<double> counts(size_t(ranks), 0.0);
    counts[size_t(comm_.rank())] = double(inner_->num_fluid());
    comm_.sum(counts.data(), ranks);
    if (imbalance(counts) <= opt_.rebalance_above) return;
    // The counts along the axis on the solver's backend: only the bins
    // leave the device, not the particles.
    AxisHistogram hist = AxisHistogram::over(plan_.lo, plan_.hi, plan_.bin);
    hist.counts = inner_->axis_counts(plan_.axis, hist.lo, hist.width, hist.counts.size());
    comm_.sum(hist.counts.data(), int(hist.counts.size()));
    const std::vector<double> target = balanced_cuts(hist, ranks, plan_.lo, plan_.hi, plan_.min_width);
    const double reach = 0.49 * plan_.min_width;
    bool moved = false;
    for (size_t k = 0; k < target.size(); ++k) {
      const double c = std::clamp(target[k], plan_.cuts[k] - reach, plan_.cuts[k] + reach);
      moved = moved || c != plan_.cuts[k];
      plan_.cuts[k] = c;
    }
    if (!moved) return;  // held at the least slab width
    inner_->set_slab(bounds());
    sum_totals();
  }

  SlabBounds bounds() const {
    SlabBounds b = slab_bounds(plan_, comm_.rank());
    b.overlap_above = opt_.overlap_above;
    return b;
  }

  // Declared first: the inner solver uses it until it is destroyed.
  std::unique_ptr<ParticleTransport> transport_;
  Comm& comm_;
  SlabPlan plan_;
  SlabOptions opt_;
  std::unique_ptr<Solver> inner_;
  StepLimits limits_;  // last_limits
  std::vector<double> totals_{0.0, 0.0, 0.0};  // owned, removed, clamped: over all ranks
  HostParticles gathered_;
  uint64_t gathered_step_ = ~uint64_t(0);
  struct {
    std::vector<uint32_t> id;
    std::vector<Float4> pos, vel;  // x, density; v
  } owned_;  // this rank's own particles at the last output frame
  uint64_t owned_step_ = ~uint64_t(0);
  SolverInput frame_in_;  // the run's input without its fluid: rank 0's frame grid
  SolverMaker make_;
  std::unique_ptr<Solver> frame_;  // rank 0, frame_view: the gathered particles, sorted
};

}  // namespace

size_t held_particles(const SolverInput& in, const SlabPlan& plan, int rank) {
  const double lo = plan.slab_lo(rank) - plan.halo, hi = plan.slab_hi(rank) + plan.halo;
  size_t n = 0;
  for (const Float4& p : in.fluid_pos_rho) {
    const double x = along(xyz(p), plan.axis);
    n += (rank == 0 || x >= lo) && (rank == plan.ranks() - 1 || x < hi);
  }
  return n;
}

SlabPlan plan_slabs(const SolverInput& in, int ranks, int axis) {
  if (axis < -1 || axis > 2) throw std::logic_error("plan_slabs: an axis other than -1 (auto), 0, 1 or 2");
  const Aabb& t = in.params.tank;
  SlabPlan p;
  p.halo = p.min_width = 2.0 * double(in.params.kernel.support());
  p.halo_free = double(in.params.kernel.support());
  // PBF's neighbours are found once per step at x*, within its own support,
  // and its walls need no fluid sums (sph/pbf_solver.inl).
  if (in.kind == SolverKind::Pbf) p.halo = p.halo_free = double(in.pbf.kernel.s);
  // DFSPH's: within its support at the step's end, kept until the next; its
  // walls are planes or wall particles that need no fluid sums.
  if (in.kind == SolverKind::Dfsph) p.halo = p.halo_free = double(in.dfsph.kernel.support());
  // A ghost's owner is a neighbouring slab (sph/exchange.h; PBF's and
  // DFSPH's refresh lists rely on it).
  if (p.halo_free > p.min_width) throw std::logic_error("plan_slabs: a halo wider than the least slab");
  p.bin = 0.5 * double(in.params.spacing);
  auto length = [&](int a) { return double(along(t.max, a) - along(t.min, a)); };
  int longest = 0;
  for (int a = 1; a < 3; ++a)
    if (length(a) > length(longest)) longest = a;
  // Every axis that holds the slabs, cut at its quantiles: the one whose
  // busiest rank holds the fewest particles (slabs.h); the longest first, so
  // that it wins a tie.
  // (An axis asked for is taken where it holds them; the others' counts are
  // still given, for the run's report.)
  std::vector<double> cuts[3];
  int best = -1;
  for (int a : {longest, (longest + 1) % 3, (longest + 2) % 3}) {
    const double lo = along(t.min, a), hi = along(t.max, a);
    if (ranks > 1 && hi - lo < ranks * p.min_width * (1.0 - 1e-9)) continue;
    AxisHistogram h = AxisHistogram::over(lo, hi, p.bin);
    for (const Float4& q : in.fluid_pos_rho) h.add(along(xyz(q), a));
    cuts[a] = balanced_cuts(h, ranks, lo, hi, p.min_width);
    p.held[a] = most_held(h, cuts[a], p.halo_free);
    if (axis >= 0 ? a == axis : best < 0 || p.held[a] < p.held[best]) best = a;
  }
  if (best < 0) {  // no axis holds them: the numbers of the one that holds the most, or of the one asked for
    const int a = axis >= 0 ? axis : longest;
    check_rank_count(ranks, along(t.min, a), along(t.max, a), p.min_width,
                     axis >= 0 ? std::string(axis_name(a)) : "the domain's longest axis (" + std::string(axis_name(a)) + ")");
    throw std::logic_error("plan_slabs: no axis holds the slabs, yet the count check passed");
  }
  p.axis = best;
  p.lo = along(t.min, best);
  p.hi = along(t.max, best);
  p.cuts = std::move(cuts[best]);
  return p;
}

std::unique_ptr<Solver> make_slab_solver(SolverInput in, const SlabPlan& plan, Comm& comm, Backend backend,
                                         const SolverMaker& make, const SlabOptions& opt) {
  if (plan.ranks() != comm.size()) throw std::logic_error("make_slab_solver: a plan for another rank count");
  if (!in.skins.empty()) throw std::invalid_argument("a run over several ranks cannot carry obstacles' skin waves");
  const uint32_t total = uint32_t(in.fluid_pos_rho.size());
  // PBF's and DFSPH's refresh lists sort ids of kRankIdBits (sph/exchange.h).
  static_assert(kRankIdBits == 30, "the message below names 2^30");
  for (uint32_t i = 0; i < total; ++i)
    if ((in.fluid_id.empty() ? i : in.fluid_id[i]) >= (1u << kRankIdBits))
      throw std::invalid_argument("a run over several ranks takes particle ids below 2^30 (1,073,741,824); id " +
                                  std::to_string(in.fluid_id.empty() ? i : in.fluid_id[i]) + " is not");
  std::vector<Float4> pos, vel;
  std::vector<uint32_t> ids;
  for (uint32_t i = 0; i < total; ++i)
    if (plan.owner(along(xyz(in.fluid_pos_rho[i]), plan.axis)) == comm.rank()) {
      pos.push_back(in.fluid_pos_rho[i]);
      vel.push_back(in.fluid_vel[i]);
      ids.push_back(in.fluid_id.empty() ? i : in.fluid_id[i]);
    }
  in.fluid_pos_rho = std::move(pos);
  in.fluid_vel = std::move(vel);
  in.fluid_id = std::move(ids);
  auto transport = backend == Backend::Cuda ? make_nccl_transport(comm) : make_mpi_transport(comm);
  SolverInput frame_in;
  if (opt.frame_view && comm.rank() == 0) {
    frame_in = in;
    frame_in.presence = PresenceMode::Off;
    frame_in.fluid_pos_rho.clear();
    frame_in.fluid_vel.clear();
  }
  in.transport = transport.get();
  auto slab = std::make_unique<SlabSolver>(std::move(transport), comm, plan, opt,
                                           std::move(frame_in), make);
  slab->start(make(in));
  return slab;
}

}  // namespace sphray
