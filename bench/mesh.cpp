#include "mesh.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <ostream>
#include <random>

#include "bench/sim.h"
#include "mesh/mesh.h"
#include "pipeline/setup.h"

namespace sphray {

namespace {

std::unique_ptr<MeshProbe> make_probe(Backend b) {
  return b == Backend::Cuda ? make_cuda_mesh_probe() : make_cpu_mesh_probe();
}

}  // namespace

std::vector<BenchMeshRow> bench_mesh(Backend b, const BenchMeshOptions& opt, std::ostream& log) {
  std::vector<BenchMeshRow> rows;
  auto probe = make_probe(b);
  const double R = 1.0, dx = R / 50.0;  // a ball 100 spacings across
  for (const int level : opt.levels) {
    const TriangleMesh m = sphere_mesh({0, 0, 0}, R, level);
    const MeshInput in = mesh_input(m);
    const std::vector<Vec3f>& verts = in.vertices;
    const std::vector<uint32_t>& idx = in.indices;
    std::vector<Vec3f> moved;
    for (const Vec3f& v : verts) moved.push_back(v * 1.1f + Vec3f{0.05f, 0, 0});
    BenchMeshRow row;
    row.triangles = uint32_t(m.size());
    row.particles = opt.particles;
    log << "  " << row.triangles << " triangles\n";
    std::vector<double> build, refit;
    for (int k = 0; k < opt.warmup + opt.frames; ++k) {
      const double ms = probe->build(verts, idx);
      if (k >= opt.warmup) build.push_back(ms);
    }
    for (int k = 0; k < opt.warmup + opt.frames; ++k) {
      const double ms = probe->refit(k % 2 ? verts : moved);
      if (k >= opt.warmup) refit.push_back(ms);
    }
    probe->refit(verts);
    row.build_ms = median(build);
    row.refit_ms = median(refit);
    // Paths: near (starting within two spacings outside the surface, half a
    // spacing long, biased inward) and spread (uniform in the box 1.5 R).
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0), s(-1.0, 1.0);
    auto unit = [&] {
      Vec3d d;
      do d = {s(rng), s(rng), s(rng)}; while (length2(d) > 1.0 || length2(d) < 1e-6);
      return d * (1.0 / length(d));
    };
    for (const bool near : {true, false}) {
      std::vector<Vec3f> from(opt.particles), to(opt.particles);
      for (uint32_t i = 0; i < opt.particles; ++i) {
        Vec3d p, q;
        if (near) {
          const Vec3d r = unit();
          p = r * (R + dx * (0.02 + 2.0 * u(rng)));
          q = p + (unit() - r) * (0.5 * dx);
        } else {
          p = Vec3d{s(rng), s(rng), s(rng)} * (1.5 * R);
          q = p + unit() * (0.5 * dx);
        }
        from[i] = {float(p.x), float(p.y), float(p.z)};
        to[i] = {float(q.x), float(q.y), float(q.z)};
      }
      probe->set_paths(from, to);
      std::vector<double> ms;
      uint32_t stopped = 0;
      for (int k = 0; k < opt.warmup + opt.frames; ++k) {
        const double t = probe->collide(stopped);
        if (k >= opt.warmup) ms.push_back(t);
      }
      if (near) {
        row.collide_near_ms = median(ms);
        row.stopped_near = double(stopped) / opt.particles;
      } else {
        row.collide_box_ms = median(ms);
      }
    }
    rows.push_back(row);
  }
  return rows;
}

nlohmann::json to_json(const std::vector<BenchMeshRow>& rows, Backend b, const BenchMeshOptions& opt) {
  nlohmann::json j = bench_json("mesh", b, "median ms", {});
  j["warmup"] = opt.warmup;
  j["measured"] = opt.frames;
  for (const auto& r : rows)
    j["rows"].push_back({{"triangles", r.triangles}, {"particles", r.particles}, {"build_ms", r.build_ms},
                         {"refit_ms", r.refit_ms}, {"collide_near_ms", r.collide_near_ms},
                         {"collide_box_ms", r.collide_box_ms}, {"stopped_near_share", r.stopped_near}});
  return j;
}

void print_table(const std::vector<BenchMeshRow>& rows, std::ostream& out) {
  out << std::setw(10) << "triangles" << std::setw(10) << "build" << std::setw(10) << "refit" << std::setw(11)
      << "particles" << std::setw(14) << "collide near" << std::setw(9) << "stopped" << std::setw(13) << "collide box"
      << "   (median ms)\n";
  out << std::fixed << std::setprecision(3);
  for (const auto& r : rows)
    out << std::setw(10) << r.triangles << std::setw(10) << r.build_ms << std::setw(10) << r.refit_ms << std::setw(11)
        << r.particles << std::setw(14) << r.collide_near_ms << std::setw(8) << std::setprecision(1)
        << 100 * r.stopped_near << "%" << std::setprecision(3) << std::setw(13) << r.collide_box_ms << "\n";
}

}  // namespace sphray
