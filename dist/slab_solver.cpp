#include "slab_solver.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

namespace sphray {

namespace {

// A particle as it travels between ranks.
struct Record {
  Float4 pos, vel, flow;
  uint32_t id;
  uint32_t status;
};

// A particle as rank 0 gathers it for the outputs.
struct Owned {
  uint32_t id;
  float pos[3], vel[3], density;
};

template <class T>
void append(std::vector<char>& buf, const T& v) {
  const size_t at = buf.size();
  buf.resize(at + sizeof(T));
  std::memcpy(buf.data() + at, &v, sizeof(T));
}

template <class T>
std::vector<T> records_of(const std::vector<char>& buf) {
  std::vector<T> out(buf.size() / sizeof(T));
  if (!out.empty()) std::memcpy(out.data(), buf.data(), out.size() * sizeof(T));
  return out;
}

float coordinate(const Float4& p, int axis) { return axis == 0 ? p.x : axis == 1 ? p.y : p.z; }

class SlabSolver final : public Solver {
 public:
  SlabSolver(std::unique_ptr<Solver> inner, Comm& comm, SlabPlan plan, uint32_t total, double bin_width,
             const SlabOptions& opt)
      : inner_(std::move(inner)), comm_(comm), plan_(std::move(plan)), opt_(opt), bin_width_(bin_width),
        ghost_(total, 0) {
    exchange();  // the first step's ghosts
  }

  Backend backend() const override { return inner_->backend(); }
  SolverKind kind() const override { return inner_->kind(); }
  double time() const override { return inner_->time(); }
  uint64_t steps() const override { return inner_->steps(); }
  size_t num_fluid() const override { return size_t(totals_[0]); }
  size_t num_removed() const override { return size_t(totals_[1]); }
  uint64_t num_clamped() const override { return uint64_t(totals_[2]); }
  const StepLimits& last_limits() const override { return inner_->last_limits(); }
  const StageTimes& last_stage_times() const override { return inner_->last_stage_times(); }
  void set_presence(PresenceMode mode) override { inner_->set_presence(mode); }
  PresenceMode presence_mode() const override { return inner_->presence_mode(); }
  bool has_presence() const override { return false; }  // put_fluid drops it (cmd_run refuses what needs it)
  ParticleView view() const override { return inner_->view(); }
  size_t device_bytes() const override { return inner_->device_bytes(); }
  std::vector<Vec3f> boundary_positions() const override { return inner_->boundary_positions(); }

  void step(double until) override {
    std::string error;
    int failed = comm_.size();
    try {
      inner_->step(until);
    } catch (const std::exception& e) {
      error = e.what();
      failed = comm_.rank();
    }
    comm_.min(&failed, 1);  // every rank learns whether one failed, and the first that did
    if (failed < comm_.size()) {
      comm_.broadcast(error, failed);
      throw RanksStopped("rank " + std::to_string(failed) + " of " + std::to_string(comm_.size()) + ": " + error);
    }
    exchange();
  }

  // Rank 0 receives every rank's owned particles, for the outputs.
  void gather_frame() override {
    const HostParticles h = inner_->download();
    std::vector<char> mine;
    mine.reserve(h.id.size() * sizeof(Owned));
    for (size_t i = 0; i < h.id.size(); ++i) {
      if (ghost_[h.id[i]]) continue;
      append(mine, Owned{h.id[i], {h.pos[i].x, h.pos[i].y, h.pos[i].z}, {h.vel[i].x, h.vel[i].y, h.vel[i].z},
                         h.density[i]});
    }
    const std::vector<std::vector<char>> all = comm_.gather(mine);
    gathered_ = HostParticles{};
    for (const auto& buf : all)
      for (const Owned& o : records_of<Owned>(buf)) {
        gathered_.id.push_back(o.id);
        gathered_.pos.push_back({o.pos[0], o.pos[1], o.pos[2]});
        gathered_.vel.push_back({o.vel[0], o.vel[1], o.vel[2]});
        gathered_.density.push_back(o.density);
      }
    gathered_step_ = steps();
  }

  HostParticles download() const override {
    check_gathered();
    return gathered_;
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

  // Drops the ghosts, sends each owned particle to its owner and its ghost
  // copies to the ranks whose halo it lies in, and puts the new set in.
  void exchange() {
    const FluidState s = inner_->take_fluid();
    const int me = comm_.rank(), ranks = comm_.size();
    size_t owned_after_step = 0;
    for (size_t i = 0; i < s.size(); ++i) owned_after_step += s.status[i] != kStatusGhost;
    removed_ += owned_before_ > owned_after_step ? owned_before_ - owned_after_step : 0;
    if (opt_.rebalance_every > 0 && steps() > 0 && steps() % uint64_t(opt_.rebalance_every) == 0) rebalance(s);

    std::vector<std::vector<char>> out(static_cast<size_t>(ranks));
    std::vector<char> keep;
    auto send = [&](int r, const Record& rec) { append(r == me ? keep : out[size_t(r)], rec); };
    for (size_t i = 0; i < s.size(); ++i) {
      if (s.status[i] == kStatusGhost) continue;
      Record rec{s.pos[i], s.vel[i], s.flow[i], s.id[i], s.status[i]};
      const double x = coordinate(s.pos[i], plan_.axis);
      const int owner = plan_.owner(x);
      send(owner, rec);
      rec.status = kStatusGhost;
      for (int r : {owner - 1, owner + 1})
        if (r >= 0 && r < ranks && plan_.in_halo(r, x)) send(r, rec);
    }
    std::vector<std::vector<char>> in = comm_.all_to_all(out);
    in[size_t(me)] = std::move(keep);

    FluidState next;
    for (const auto& p : s.id) ghost_[p] = 0;
    size_t owned = 0;
    for (const auto& buf : in)
      for (const Record& r : records_of<Record>(buf)) {
        next.pos.push_back(r.pos);
        next.vel.push_back(r.vel);
        next.flow.push_back(r.flow);
        next.id.push_back(r.id);
        next.status.push_back(uint8_t(r.status));
        ghost_[r.id] = r.status == kStatusGhost;
        owned += r.status != kStatusGhost;
      }
    inner_->put_fluid(next);
    owned_before_ = owned;
    totals_ = {double(owned), double(removed_), double(inner_->num_clamped())};
    comm_.sum(totals_.data(), 3);
  }

  // The cuts to the quantiles of the particles along the axis when the ranks'
  // counts differ by more than opt_.rebalance_above.
  void rebalance(const FluidState& s) {
    const int ranks = comm_.size();
    AxisHistogram h = AxisHistogram::over(plan_.lo, plan_.hi, bin_width_);
    std::vector<double> v(size_t(ranks) + h.counts.size(), 0.0);
    for (size_t i = 0; i < s.size(); ++i)
      if (s.status[i] != kStatusGhost) {
        v[size_t(comm_.rank())] += 1.0;
        h.add(coordinate(s.pos[i], plan_.axis));
      }
    std::copy(h.counts.begin(), h.counts.end(), v.begin() + ranks);
    comm_.sum(v.data(), int(v.size()));
    if (imbalance(std::vector<double>(v.begin(), v.begin() + ranks)) <= opt_.rebalance_above) return;
    std::copy(v.begin() + ranks, v.end(), h.counts.begin());
    plan_.cuts = balanced_cuts(h, ranks, plan_.lo, plan_.hi, plan_.min_width);
    ++rebalances_;
  }

  std::unique_ptr<Solver> inner_;
  Comm& comm_;
  SlabPlan plan_;
  SlabOptions opt_;
  double bin_width_;
  std::vector<uint8_t> ghost_;  // per id: a ghost here
  size_t owned_before_ = 0, removed_ = 0;
  std::vector<double> totals_{0.0, 0.0, 0.0};  // owned, removed, clamped: over all ranks
  uint64_t rebalances_ = 0;
  HostParticles gathered_;
  uint64_t gathered_step_ = ~uint64_t(0);
};

}  // namespace

SlabPlan plan_slabs(const SolverInput& in, int ranks) {
  const Aabb& t = in.params.tank;
  const double ext[3] = {double(t.max.x - t.min.x), double(t.max.y - t.min.y), double(t.max.z - t.min.z)};
  SlabPlan p;
  p.axis = ext[1] > ext[p.axis] ? 1 : p.axis;
  p.axis = ext[2] > ext[p.axis] ? 2 : p.axis;
  p.lo = p.axis == 0 ? t.min.x : p.axis == 1 ? t.min.y : t.min.z;
  p.hi = p.axis == 0 ? t.max.x : p.axis == 1 ? t.max.y : t.max.z;
  p.halo = p.min_width = 2.0 * double(in.params.kernel.support());
  check_rank_count(ranks, p.lo, p.hi, p.min_width, axis_name(p.axis));
  AxisHistogram h = AxisHistogram::over(p.lo, p.hi, 0.5 * double(in.params.spacing));
  for (const Float4& q : in.fluid_pos_rho) h.add(coordinate(q, p.axis));
  p.cuts = balanced_cuts(h, ranks, p.lo, p.hi, p.min_width);
  return p;
}

std::unique_ptr<Solver> make_slab_solver(SolverInput in, Comm& comm, const SolverMaker& make, const SlabOptions& opt) {
  if (in.kind != SolverKind::Wcsph)
    throw std::invalid_argument(std::string("a run over several ranks needs sph.solver \"wcsph\" (this is \"") +
                                solver_name(in.kind) + "\")");
  if (!in.skins.empty()) throw std::invalid_argument("a run over several ranks cannot carry obstacles' skin waves");
  const SlabPlan plan = plan_slabs(in, comm.size());
  const uint32_t total = uint32_t(in.fluid_pos_rho.size());
  std::vector<Float4> pos, vel;
  std::vector<uint32_t> ids;
  for (uint32_t i = 0; i < total; ++i)
    if (plan.owner(coordinate(in.fluid_pos_rho[i], plan.axis)) == comm.rank()) {
      pos.push_back(in.fluid_pos_rho[i]);
      vel.push_back(in.fluid_vel[i]);
      ids.push_back(i);
    }
  in.fluid_pos_rho = std::move(pos);
  in.fluid_vel = std::move(vel);
  in.fluid_id = std::move(ids);
  in.reduce_step_stats = [&comm](StepStats& s) {
    float v[2] = {s.max_speed2, s.max_accel2};
    comm.max(v, 2);
    s.max_speed2 = v[0];
    s.max_accel2 = v[1];
  };
  const double bin = 0.5 * double(in.params.spacing);
  return std::make_unique<SlabSolver>(make(in), comm, plan, total, bin, opt);
}

}  // namespace sphray
