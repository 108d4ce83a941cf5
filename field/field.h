// The density field as the host sees it: the volume geometry and falloff,
// and one builder interface over both backends (builders.h, field_impl.inl). docs/field.md describes the method and its numbers.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "anisotropy.h"
#include "config.h"
#include "volume.h"
#include "sph/solver.h"

namespace sphray {

struct FieldSetup {
  VolumeGeom geom;
  FieldShape shape;
  // Where mark_occupied: a cell with at least full_count particles whose face
  // neighbours each hold face_count is filled whole (FullCellFlags) with full_fill.
  uint32_t full_count = 1, face_count = 1;
  float full_fill = 0;
  // The presence builder marks the voxel of each particle after the coarse
  // fill (refine > 0, or anisotropic kernels); otherwise (refine 0, spheres)
  // any occupied cell is just inside (the paper's rule).
  bool mark_occupied = false;
  // Spheres, ellipsoids (aniso: field/anisotropy.h) or Zhu & Bridson's
  // surface (zhu_bridson; the gather builder only: builders.h, ZhuBridsonGather).
  FieldKernel kernel = FieldKernel::Isotropic;
  AnisotropyParams aniso;
  ZhuBridsonParams zhu_bridson;
  // The presence builder with ellipsoids leaves out the particles whose splat
  // box lies in full cells whatever their ellipsoid (EllipsoidPass): on by
  // default; off only to compare against.
  bool leave_out_buried = true;
};

// The reach [m] of the builder's pass that sorts the particles by a grid of
// half of it (anisotropy_grid): the ellipsoids' covariance radius, or Zhu &
// Bridson's R; 0 where no pass sorts (spheres).
inline float field_sort_radius(const FieldSetup& s) {
  return s.kernel == FieldKernel::ZhuBridson ? s.zhu_bridson.radius * s.geom.voxel
         : s.kernel == FieldKernel::Anisotropic ? s.aniso.radius
                                                : 0.0f;
}

// What a build did (counted only when asked; see docs/field.md).
struct FieldCounts {
  bool counted = false;
  uint64_t init_writes = 0;  // voxels written by the zero / coarse fill
  uint64_t pairs = 0;        // particle-voxel distance evaluations
  uint64_t touched = 0;      // voxel reads or writes by the splat / gather
  uint64_t atomics = 0;      // atomic read-modify-writes issued (CAS retries included)
  uint64_t skipped = 0;      // splat visits that found the voxel saturated
  uint64_t working = 0;      // threads (particles x lanes, or voxels) that evaluated a distance
  uint64_t longest = 0;      // the most distance evaluations of one thread
};

// Threads per particle a splat may run with (FieldBuilder::build).
inline bool valid_group(int group) { return group == 1 || group == 4 || group == 8 || group == 32; }

class FieldBuilder {
 public:
  virtual ~FieldBuilder() = default;
  virtual Backend backend() const = 0;
  virtual const FieldSetup& setup() const = 0;
  virtual FieldKind kind() const = 0;  // fixed when the builder is made
  // Builds the volume from a solver's particles (same backend). `count` adds
  // the counters of FieldCounts (slower; not for timing). `group`: threads per
  // particle for the splats, 1, 4, 8 or 32 (0: the backend's choice, docs/field.md).
  virtual void build(const ParticleView& particles, bool count = false, int group = 0) = 0;
  virtual double last_ms() const = 0;  // device time of the last build (CUDA events / wall clock on CPU)
  virtual double last_anisotropy_ms() const = 0;  // ... of which the ellipsoids' pass (presence: with its marks; 0: spheres)
  virtual const FieldCounts& last_counts() const = 0;
  virtual const float* data() const = 0;  // the volume, x fastest, in the backend's memory
  virtual std::vector<float> download() const = 0;
  virtual size_t device_bytes() const = 0;
};

std::unique_ptr<FieldBuilder> make_cpu_field_builder(const FieldSetup& s, FieldKind kind);
std::unique_ptr<FieldBuilder> make_cuda_field_builder(const FieldSetup& s, FieldKind kind);  // throws if CUDA is unavailable
std::unique_ptr<FieldBuilder> make_field_builder(Backend b, const FieldSetup& s, FieldKind kind);

}  // namespace sphray
