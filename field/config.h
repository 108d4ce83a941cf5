// The scene's "field" section (docs/field.md, docs/scenes.md): which builder
// makes the density field and the falloff it splats, with the defaults in
// one place.
#pragma once

#include <string>

#include "core/config_reader.h"

namespace sphray {

enum class FieldKind { Naive, Presence, Gather };
const char* field_kind_name(FieldKind k);
FieldKind parse_field_kind(const std::string& name);  // throws std::invalid_argument

// Each particle's kernel: a sphere, or an ellipsoid stretched along the
// local surface (Yu & Turk 2013; field/anisotropy.h, docs/field.md); or no
// sum of kernels but the distance to the neighbours' weighted mean position
// less a particle radius (Zhu & Bridson 2005; field/builders.h, ZhuBridsonGather).
enum class FieldKernel { Isotropic, Anisotropic, ZhuBridson };
constexpr FieldKernel kFieldKernels[] = {FieldKernel::Isotropic, FieldKernel::Anisotropic, FieldKernel::ZhuBridson};
const char* field_kernel_name(FieldKernel k);

struct AnisotropyConfig {
  double radius = 3.0;     // neighbourhood of the covariance [particle spacings]
  double stretch = 4.0;    // largest over smallest axis, at most (>= 1; 1: spheres)
  double smoothing = 0.9;  // kernel centre moved this share of the way to the neighbours' weighted mean (0..1)
  int min_neighbours = 8;  // fewer neighbours than this: a sphere (spray, lone particles)
  bool mirror_walls = true;  // the tank's walls as mirrors: a wall is no free side of the neighbourhood (anisotropy.h)
};

struct ZhuBridsonConfig {
  double radius = 3.0;            // R: the neighbours' reach [voxels]
  double particle_radius = 0.78;  // r: the surface lies r from their weighted mean [voxels] (a lone particle's: at least 0.95)
  bool mirror_walls = true;       // the tank's walls as mirrors: the liquid meets them instead of pulling back (volume.h)
};

struct FieldConfig {
  // Built at every output frame (its time in the summary), not only where an
  // output draws or exports it: the scene has a "field" section whose
  // "every_frame" is true (the key's default).
  bool every_frame = false;
  FieldKind builder = FieldKind::Presence;
  int refine = 2;                         // voxels per SPH cell edge = 2^refine
  double radius = 2.0;                    // influence radius R [voxels]
  double core = 0.5;                      // finite core of the inverse-square falloff [voxels]
  double clip = 4.0;                      // saturation value as a multiple of the iso value
  double min_extent = 1.0;                // presence builder: extent toward a fully surrounded side [voxels]
  double shrink_from = 0.5;               // presence builder: a side keeps its full extent up to this presence
  double full_fraction = 0.9;             // presence coarse fill (refine > 0): share of (cell/dx)^3 that fills a cell
  bool full_value_clip = true;            // ... and the value it gets: saturated ("clip") or just inside ("coarse")
  FieldKernel kernel = FieldKernel::Isotropic;
  AnisotropyConfig anisotropy;
  ZhuBridsonConfig zhu_bridson;
};

FieldConfig read_field_config(const ConfigReader& r);

}  // namespace sphray
