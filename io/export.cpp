#include "export.h"
#include "sph/skin.h"

#include <algorithm>
#include <functional>
#include <memory>
#include <mutex>
#include <numeric>
#include <omp.h>
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
  std::vector<float> solver_pressure;  // Solver::pressures (DFSPH), sorted order; empty: Tait from the density
  VolumeGeom geom{};
  float iso = 0;
  std::vector<Frame::Skin> skins;
  std::vector<uint32_t> rank, slot;  // scratch of convert()
  Frame out;                         // made by convert(), its buffers kept for the next frame
};

// s.out = the snapshot in ascending id order. It must keep up with a run
// that exports every few steps: it runs on half the cores, and writes into
// the buffers of earlier frames (fresh ones cost their zero fill and page
// faults).
void convert(Snapshot& s) {
  const RawParticles& p = s.p;
  const int64_t n = int64_t(p.id.size());
  const bool big = n > 65536;
  // Half the cores: the run's thread (waiting on the device) and the writer
  // want theirs; with all of them the team waits on the thread that those
  // displace (docs/notebook/benchmarks-history.md, "HDF5 export").
  const int team = std::max(1, std::min(omp_get_max_threads(), omp_get_num_procs() / 2));
  uint32_t max_id = 0;
#pragma omp parallel for reduction(max : max_id) if (big) num_threads(team)
  for (int64_t k = 0; k < n; ++k) max_id = std::max(max_id, p.id[size_t(k)]);
  // Each particle's row: its id when every initial particle is present (ids
  // are unique initial indices), else its id's rank among those present
  // (removed particles leave gaps).
  const uint32_t* row = p.id.data();
  if (n > 0 && int64_t(max_id) + 1 != n) {
    s.slot.assign(size_t(max_id) + 1, 0);
    for (int64_t k = 0; k < n; ++k) s.slot[p.id[size_t(k)]] = 1;
    std::exclusive_scan(s.slot.begin(), s.slot.end(), s.slot.begin(), 0u);
    s.rank.resize(size_t(n));
    for (int64_t k = 0; k < n; ++k) s.rank[size_t(k)] = s.slot[p.id[size_t(k)]];
    row = s.rank.data();
  }
  Frame& f = s.out;
  f.time = s.time;
  f.step = s.step;
  f.dt = s.dt;
  const bool vel = s.velocity && int64_t(p.vel.size()) == n, pres = s.presence && int64_t(p.presence.size()) == 6 * n;
  f.id.resize(size_t(n));
  f.position.resize(3 * size_t(n));
  f.velocity.resize(vel ? 3 * size_t(n) : 0);
  f.density.resize(s.density ? size_t(n) : 0);
  f.pressure.resize(s.pressure ? size_t(n) : 0);
  f.presence.resize(pres ? 6 * size_t(n) : 0);
#pragma omp parallel for if (big) num_threads(team)
  for (int64_t k = 0; k < n; ++k) {
    const size_t i = size_t(k), r = row[i];
    const Float4& q = p.pos[i];
    f.id[r] = p.id[i];
    f.position[3 * r] = q.x, f.position[3 * r + 1] = q.y, f.position[3 * r + 2] = q.z;
    if (vel) {
      const Float4& v = p.vel[i];
      f.velocity[3 * r] = v.x, f.velocity[3 * r + 1] = v.y, f.velocity[3 * r + 2] = v.z;
    }
    if (s.density) f.density[r] = q.w;
    if (s.pressure) f.pressure[r] = s.solver_pressure.empty() ? tait_pressure(s.prm, q.w) : s.solver_pressure[i];
    if (pres)
      for (size_t d = 0; d < 6; ++d) f.presence[6 * r + d] = p.presence[d * size_t(n) + i];
  }
  f.skins.swap(s.skins);
  s.skins.clear();
  f.field.swap(s.field);  // the next capture downloads into the other buffer
  s.field.clear();
  if (!f.field.empty()) {
    f.field_dims[0] = s.geom.nx; f.field_dims[1] = s.geom.ny; f.field_dims[2] = s.geom.nz;
    f.field_origin[0] = s.geom.origin.x; f.field_origin[1] = s.geom.origin.y; f.field_origin[2] = s.geom.origin.z;
    f.field_voxel = s.geom.voxel;
    f.field_iso = s.iso;
  }
}

// Snapshots are reused: a fresh host buffer per frame costs its page faults
// and zero fill on the run's thread, about as much as the copy itself.
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

std::function<std::shared_ptr<const Frame>()> capture_frame(const Solver& solver, const SphParams& prm,
                                                            const std::set<std::string>& fields,
                                                            const FieldBuilder* field) {
  auto s = pool().take();
  s->field.clear();
  s->velocity = fields.count("velocity") > 0;
  s->density = fields.count("density") > 0;
  s->pressure = fields.count("pressure") > 0;
  s->presence = fields.count("presence") > 0;
  solver.download_raw(s->p, s->velocity, s->presence);
  s->solver_pressure.clear();
  if (s->pressure) s->solver_pressure = solver.pressures();
  s->time = solver.time();
  s->step = solver.steps();
  s->dt = solver.last_limits().dt;
  s->prm = prm;
  s->skins.clear();
  if (const SkinSet* skins = solver.skins())
    for (size_t k = 0; k < skins->size(); ++k)
      s->skins.push_back({skins->geometry(k).input.obstacle, skins->geometry(k).map.n, skins->heights(k)});
  if (field && fields.count("field")) {
    s->field = field->download();
    s->geom = field->setup().geom;
    s->iso = field->setup().shape.iso;
  }
  return [s] {
    if (s->p.ready) s->p.ready();  // the copies off the device, behind the run's next steps
    convert(*s);
    // back to the pool, with the frame's buffers, once the writer is done with it
    return std::shared_ptr<const Frame>(&s->out, [s](const Frame*) { pool().give(s); });
  };
}

Frame frame_of(const Solver& s, const SphParams& prm, const std::set<std::string>& fields, const FieldBuilder* field) {
  return *capture_frame(s, prm, fields, field)();
}

}  // namespace sphray
