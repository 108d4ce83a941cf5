// `sphray bench mesh`: the cost of triangle-mesh obstacles on their own. For
// icospheres of increasing triangle counts: the BVH build (Morton codes,
// sort, nodes, boxes) and its refit after the vertices move, and the
// collision pass (sph/obstacles.h, stop_at_obstacles) over a million
// particle steps, both near the surface (every path within two spacings of
// it, many entering) and spread over the mesh's box. Device events after
// warm-up, medians.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <memory>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/device.h"
#include "core/vec.h"

namespace sphray {

struct BenchMeshOptions {
  std::vector<int> levels{4, 6, 8};  // icosphere subdivisions: 20 * 4^level triangles
  uint32_t particles = 1000000;
  int warmup = 2, frames = 10;
};

struct BenchMeshRow {
  uint32_t triangles = 0, particles = 0;
  double build_ms = 0, refit_ms = 0, collide_near_ms = 0, collide_box_ms = 0;
  double stopped_near = 0;  // share of the near paths that were stopped
};

std::vector<BenchMeshRow> bench_mesh(Backend b, const BenchMeshOptions& opt, std::ostream& log);
nlohmann::json to_json(const std::vector<BenchMeshRow>& rows, Backend b, const BenchMeshOptions& opt);
void print_table(const std::vector<BenchMeshRow>& rows, std::ostream& out);

// The timed work on one backend (bench/mesh_probe.inl).
class MeshProbe {
 public:
  virtual ~MeshProbe() = default;
  // Builds the tree (kept for the calls below); device ms of the build.
  virtual double build(const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices) = 0;
  virtual double refit(const std::vector<Vec3f>& vertices) = 0;
  // Uploads the paths (from -> to) that collide() then stops at the mesh.
  virtual void set_paths(const std::vector<Vec3f>& from, const std::vector<Vec3f>& to) = 0;
  virtual double collide(uint32_t& stopped) = 0;
};
std::unique_ptr<MeshProbe> make_cpu_mesh_probe();
std::unique_ptr<MeshProbe> make_cuda_mesh_probe();

}  // namespace sphray
