#include "solver.h"

#include <algorithm>

#include "integrate.h"
#include "skin.h"

namespace sphray {

FlowSums flow_sums_of(const HostParticles& p) {
  FlowSums f;
  for (size_t i = 0; i < p.pos.size(); ++i) {
    if (!p.status.empty() && p.status[i] == kStatusGhost) continue;
    f.max_x = std::max(f.max_x, double(p.pos[i].x));
    f.speed2_sum += double(length2(p.vel[i]));
  }
  return f;
}

FlowSums Solver::flow_sums() const { return flow_sums_of(download()); }

std::vector<double> Solver::axis_counts(int axis, double lo, double bin, size_t bins) const {
  std::vector<double> out(bins, 0.0);
  if (bins == 0) return out;
  const HostParticles h = download();
  for (size_t i = 0; i < h.pos.size(); ++i) {
    if (!h.status.empty() && h.status[i] == kStatusGhost) continue;
    out[axis_bin(double(along(h.pos[i], axis)), lo, bin, uint32_t(bins))] += 1.0;
  }
  return out;
}

const char* solver_name(SolverKind k) {
  switch (k) {
    case SolverKind::Pbf: return "pbf";
    case SolverKind::Dfsph: return "dfsph";
    default: return "wcsph";
  }
}

#if !defined(SPHRAY_HAVE_CUDA)
std::unique_ptr<Solver> make_cuda_solver(const SolverInput&) { throw_no_cuda(); }
std::unique_ptr<SkinSet> make_cuda_skin_set(std::vector<SkinGeometry>, const SphParams&) { throw_no_cuda(); }
#endif

}  // namespace sphray
