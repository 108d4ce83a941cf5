#include "host_particles.h"

#include <stdexcept>

#include "nsearch_probe.h"

namespace sphray {

HostParticleSet::HostParticleSet(const GridGeom& g, const std::vector<Vec3f>& points,
                                 const std::vector<float>& presence_in)
    : grid(g) {
  const GridBuild b = build_grid(Backend::Cpu, g, points);
  const size_t n = b.offsets.back();  // points outside the grid sort last and are dropped
  pos.resize(n);
  for (size_t k = 0; k < n; ++k) {
    const Vec3f p = points[b.order[k]];
    pos[k] = {p.x, p.y, p.z, 0.0f};
  }
  offsets = b.offsets;
  fine_offsets = b.fine_offsets;
  if (!presence_in.empty()) {
    if (presence_in.size() != 6 * points.size())
      throw std::invalid_argument("HostParticleSet: presence must hold 6 values per point");
    presence.resize(6 * n);
    for (size_t d = 0; d < 6; ++d)
      for (size_t k = 0; k < n; ++k) presence[d * n + k] = presence_in[d * points.size() + b.order[k]];
  }
}

ParticleView HostParticleSet::view() const {
  return {Backend::Cpu, uint32_t(pos.size()), pos.data(), offsets.data(), presence.empty() ? nullptr : presence.data(),
          grid, fine_offsets.data()};
}

}  // namespace sphray
