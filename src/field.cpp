#include "field.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "scene.h"
#include "setup.h"

namespace sphray {

const char* field_kind_name(FieldKind k) {
  switch (k) {
    case FieldKind::Naive: return "naive";
    case FieldKind::Presence: return "presence";
    case FieldKind::Gather: return "gather";
  }
  return "?";
}

FieldKind parse_field_kind(const std::string& name) {
  if (name == "naive") return FieldKind::Naive;
  if (name == "presence") return FieldKind::Presence;
  if (name == "gather") return FieldKind::Gather;
  throw std::invalid_argument("unknown field builder '" + name + "' (naive, presence or gather)");
}

FieldSetup make_field_setup(const Scene& s) {
  const GridGeom g = measure_scene(s).grid;
  const Scene::Field& f = s.field;
  FieldSetup out;
  VolumeGeom& v = out.geom;
  v.refine = f.refine;
  const int per = 1 << f.refine;
  v.voxel = g.cell_size / float(per);
  const double lo[3] = {s.tank.min.x, s.tank.min.y, s.tank.min.z}, hi[3] = {s.tank.max.x, s.tank.max.y, s.tank.max.z};
  const double o[3] = {g.origin.x, g.origin.y, g.origin.z};
  const int n[3] = {g.nx, g.ny, g.nz};
  int dims[3];
  for (int a = 0; a < 3; ++a) {
    int c0 = int(std::floor((lo[a] - o[a]) / g.cell_size));
    // An open top keeps the grid's room above the rim: splashes there are still liquid.
    int c1 = (a == 2 && s.open_top) ? n[a] : int(std::ceil((hi[a] - o[a]) / g.cell_size));
    c0 = std::clamp(c0, 0, n[a] - 1);
    c1 = std::clamp(c1, c0 + 1, n[a]);
    v.cell0[a] = c0;
    dims[a] = (c1 - c0) * per;
  }
  v.nx = dims[0]; v.ny = dims[1]; v.nz = dims[2];
  v.origin = {g.origin.x + v.cell0[0] * g.cell_size, g.origin.y + v.cell0[1] * g.cell_size,
              g.origin.z + v.cell0[2] * g.cell_size};
  if (double(v.nx) * v.ny * v.nz >= 4294967295.0) {
    std::ostringstream os;
    os << s.file << ": field.refine = " << f.refine << " gives a " << v.nx << " x " << v.ny << " x " << v.nz
       << " volume: more than 2^32 voxels. Lower field.refine or raise sph.spacing.";
    throw SceneError(os.str());
  }

  FieldShape& sh = out.shape;
  sh.radius = float(f.radius);
  sh.core2 = float(f.core * f.core);
  sh.offset = float(1.0 / (f.radius * f.radius + f.core * f.core));
  sh.iso = float(1.0 / (0.75 + f.core * f.core) - sh.offset);  // f(sqrt(3)/2)
  sh.coarse = sh.iso * (1.0f + 1.0f / 1024.0f);
  sh.clip = float(f.clip) * sh.iso;
  sh.min_extent = float(f.min_extent);
  sh.shrink_from = float(f.shrink_from);
  const double per_cell = std::pow(g.cell_size / s.sph.spacing, 3.0);
  out.full_fill = f.full_value == "clip" ? sh.clip : sh.coarse;
  out.full_count = f.refine == 0 ? 1u : uint32_t(std::max(1.0, std::ceil(f.full_fraction * per_cell - 1e-9)));
  return out;
}

std::unique_ptr<FieldBuilder> make_field_builder(Backend b, const FieldSetup& s) {
  return b == Backend::Cuda ? make_cuda_field_builder(s) : make_cpu_field_builder(s);
}

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
          grid};
}

}  // namespace sphray
