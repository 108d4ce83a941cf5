#include "export.h"

#include <algorithm>
#include <functional>
#include <memory>
#include <mutex>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace sphray {

std::set<std::string> parse_export_fields(const std::string& text) {
  std::set<std::string> out;
  std::stringstream ss(text);
  for (std::string f; std::getline(ss, f, ',');) {
    if (f.empty()) continue;
    const auto& ok = exportable_fields();
    if (std::find(ok.begin(), ok.end(), f) == ok.end()) {
      std::string list;
      for (const auto& o : ok) list += (list.empty() ? "" : ", ") + o;
      throw std::runtime_error("--export-fields: unknown field '" + f + "' (position is always written; others: " + list + ")");
    }
    out.insert(f);
  }
  return out;
}

namespace {

struct Snapshot {
  RawParticles p;
  double time = 0, dt = 0;
  uint64_t step = 0;
  SphParams prm{};
  bool velocity = false, density = false, pressure = false, presence = false;
  std::vector<float> field;
  VolumeGeom geom{};
  float iso = 0;
};

Frame convert(Snapshot& s) {
  const RawParticles& p = s.p;
  const size_t n = p.id.size();
  // Ascending ids by a scatter over the id range (ids are unique initial
  // indices; removed particles leave gaps): O(n), no sort.
  uint32_t max_id = 0;
  for (uint32_t id : p.id) max_id = std::max(max_id, id);
  std::vector<int64_t> slot(n ? size_t(max_id) + 1 : 0, -1);
  for (size_t k = 0; k < n; ++k) slot[p.id[k]] = int64_t(k);
  Frame f;
  f.time = s.time;
  f.step = s.step;
  f.dt = s.dt;
  f.id.reserve(n);
  f.position.reserve(3 * n);
  const bool vel = s.velocity && p.vel.size() == n, pres = s.presence && p.presence.size() == 6 * n;
  for (int64_t i : slot) {
    if (i < 0) continue;
    const Float4& q = p.pos[size_t(i)];
    f.id.push_back(p.id[size_t(i)]);
    f.position.insert(f.position.end(), {q.x, q.y, q.z});
    if (vel) {
      const Float4& v = p.vel[size_t(i)];
      f.velocity.insert(f.velocity.end(), {v.x, v.y, v.z});
    }
    if (s.density) f.density.push_back(q.w);
    if (s.pressure) f.pressure.push_back(tait_pressure(s.prm, q.w));
    if (pres)
      for (size_t d = 0; d < 6; ++d) f.presence.push_back(p.presence[d * n + size_t(i)]);
  }
  if (!s.field.empty()) {
    f.field = std::move(s.field);
    f.field_dims[0] = s.geom.nx; f.field_dims[1] = s.geom.ny; f.field_dims[2] = s.geom.nz;
    f.field_origin[0] = s.geom.origin.x; f.field_origin[1] = s.geom.origin.y; f.field_origin[2] = s.geom.origin.z;
    f.field_voxel = s.geom.voxel;
    f.field_iso = s.iso;
  }
  return f;
}

// Snapshots are reused: a fresh 20 MB host buffer per frame costs its page
// faults and zero fill on the run's thread, about as much as the copy itself.
// Few are ever alive at once (one being captured, one queued, one written).
class SnapshotPool {
 public:
  std::shared_ptr<Snapshot> take() {
    std::lock_guard<std::mutex> lock(m_);
    if (free_.empty()) return std::make_shared<Snapshot>();
    auto s = std::move(free_.back());
    free_.pop_back();
    return s;
  }
  void give(std::shared_ptr<Snapshot> s) {
    std::lock_guard<std::mutex> lock(m_);
    if (free_.size() < 4) free_.push_back(std::move(s));
  }

 private:
  std::mutex m_;
  std::vector<std::shared_ptr<Snapshot>> free_;
};

SnapshotPool& pool() {
  static SnapshotPool p;
  return p;
}

}  // namespace

std::function<Frame()> capture_frame(const Solver& solver, const SphParams& prm, const std::set<std::string>& fields,
                                     const FieldBuilder* field) {
  auto s = pool().take();
  s->field.clear();
  s->velocity = fields.count("velocity") > 0;
  s->density = fields.count("density") > 0;
  s->pressure = fields.count("pressure") > 0;
  s->presence = fields.count("presence") > 0;
  solver.download_raw(s->p, s->velocity, s->presence);
  s->time = solver.time();
  s->step = solver.steps();
  s->dt = solver.last_limits().dt;
  s->prm = prm;
  if (field && fields.count("field")) {
    s->field = field->download();
    s->geom = field->setup().geom;
    s->iso = field->setup().shape.iso;
  }
  return [s] {
    Frame f = convert(*s);
    pool().give(s);
    return f;
  };
}

Frame frame_of(const Solver& s, const SphParams& prm, const std::set<std::string>& fields, const FieldBuilder* field) {
  return capture_frame(s, prm, fields, field)();
}

}  // namespace sphray
