// A solver that wraps another and forwards every call to it: the base of the
// decorators (an obstacle's skins, sph/skin.cpp; a run over several ranks
// driven by rank 0, dist/driven.cpp), which override what they add.
#pragma once

#include <memory>
#include <utility>

#include "solver.h"

namespace sphray {

class ForwardingSolver : public Solver {
 public:
  explicit ForwardingSolver(std::unique_ptr<Solver> inner) : inner_(std::move(inner)) {}

  Backend backend() const override { return inner_->backend(); }
  SolverKind kind() const override { return inner_->kind(); }
  void step(double until) override { inner_->step(until); }
  double time() const override { return inner_->time(); }
  uint64_t steps() const override { return inner_->steps(); }
  size_t num_fluid() const override { return inner_->num_fluid(); }
  size_t num_removed() const override { return inner_->num_removed(); }
  uint64_t num_clamped() const override { return inner_->num_clamped(); }
  const StepLimits& last_limits() const override { return inner_->last_limits(); }
  const StageTimes& last_stage_times() const override { return inner_->last_stage_times(); }
  SolveStats last_solve() const override { return inner_->last_solve(); }
  void set_presence(PresenceMode mode) override { inner_->set_presence(mode); }
  PresenceMode presence_mode() const override { return inner_->presence_mode(); }
  bool has_presence() const override { return inner_->has_presence(); }
  ParticleView view() const override { return inner_->view(); }
  size_t device_bytes() const override { return inner_->device_bytes(); }
  HostParticles download() const override { return inner_->download(); }
  FlowSums flow_sums() const override { return inner_->flow_sums(); }
  void download_raw(RawParticles& out, bool velocity, bool presence) const override {
    inner_->download_raw(out, velocity, presence);
  }
  void download_owned(RawParticles& out, bool velocity) const override { inner_->download_owned(out, velocity); }
  std::vector<Vec3f> boundary_positions() const override { return inner_->boundary_positions(); }
  std::vector<float> pressures() const override { return inner_->pressures(); }
  const float* device_pressure() override { return inner_->device_pressure(); }
  void set_slab(const SlabBounds& b) override { inner_->set_slab(b); }
  std::vector<double> axis_counts(int axis, double lo, double bin, size_t bins) const override {
    return inner_->axis_counts(axis, lo, bin, bins);
  }
  void gather_frame() override { inner_->gather_frame(); }
  SkinSet* skins() override { return inner_->skins(); }
  const SkinSet* skins() const override { return inner_->skins(); }

 protected:
  std::unique_ptr<Solver> inner_;
};

}  // namespace sphray
