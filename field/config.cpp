#include "config.h"
#include "volume.h"

#include <iterator>
#include <sstream>
#include <stdexcept>
#include <string>

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

const char* field_kernel_name(FieldKernel k) {
  switch (k) {
    case FieldKernel::Isotropic: return "isotropic";
    case FieldKernel::Anisotropic: return "anisotropic";
    case FieldKernel::ZhuBridson: return "zhu_bridson";
  }
  return "?";
}

FieldConfig read_field_config(const ConfigReader& r) {
  r.only({"builder", "refine", "radius", "core", "clip", "min_extent", "shrink_from", "full_fraction", "full_value",
          "kernel", "anisotropy", "zhu_bridson", "every_frame"});
  FieldConfig c;
  c.builder = parse_field_kind(r.string("builder", field_kind_name(c.builder), {"naive", "presence", "gather"}));
  const double refine = r.number("refine", c.refine, 0, 2);
  if (refine != int(refine)) r.fail("refine", r.at("refine"), "must be 0, 1 or 2 (voxels per cell edge = 2^refine)");
  c.refine = int(refine);
  c.radius = r.number("radius", c.radius, 1.0, 8.0);
  c.core = r.number("core", c.core, 0.05, 4.0);
  c.clip = r.number("clip", c.clip, 1.01, 1e3);
  c.min_extent = r.number("min_extent", c.min_extent, 0.0, 8.0);
  if (c.min_extent > c.radius) r.fail("min_extent", r.at("min_extent"), "must not exceed field.radius");
  c.shrink_from = r.number("shrink_from", c.shrink_from, 0.0, 0.95);
  c.full_fraction = r.number("full_fraction", c.full_fraction, 0.1, 2.0);
  c.full_value_clip = r.string("full_value", c.full_value_clip ? "clip" : "coarse", {"clip", "coarse"}) == "clip";
  c.every_frame = r.boolean("every_frame", true);  // the section's own; io/scene.cpp: false without one
  const std::string kernel =
      r.string("kernel", field_kernel_name(c.kernel),
               {field_kernel_name(kFieldKernels[0]), field_kernel_name(kFieldKernels[1]), field_kernel_name(kFieldKernels[2])});
  static_assert(std::size(kFieldKernels) == 3, "the kernel key's choices name every kernel");
  for (FieldKernel k : kFieldKernels)
    if (kernel == field_kernel_name(k)) c.kernel = k;
  if (c.kernel == FieldKernel::Anisotropic && c.builder == FieldKind::Gather)
    r.fail("kernel", r.at("kernel"), "the gather builder splats spheres only: use builder naive or presence");
  // Zhu & Bridson's surface is a per-voxel mean of the particles around it:
  // the gather builder's pass, and its default builder.
  if (c.kernel == FieldKernel::ZhuBridson) {
    if (r.has("builder") && c.builder != FieldKind::Gather)
      r.fail("builder", r.at("builder"), "the zhu_bridson kernel is built by the gather builder only");
    c.builder = FieldKind::Gather;
  }
  if (r.has("anisotropy") && c.kernel != FieldKernel::Anisotropic)
    r.fail("anisotropy", r.at("anisotropy"), "is read only with \"kernel\": \"anisotropic\"");
  if (r.has("zhu_bridson") && c.kernel != FieldKernel::ZhuBridson)
    r.fail("zhu_bridson", r.at("zhu_bridson"), "is read only with \"kernel\": \"zhu_bridson\"");
  const ConfigReader zb = r.child("zhu_bridson");
  zb.only({"radius", "particle_radius", "mirror_walls"});
  ZhuBridsonConfig& z = c.zhu_bridson;
  z.radius = zb.number("radius", z.radius, 1.0, 8.0);
  z.particle_radius = zb.number("particle_radius", z.particle_radius, 0.05, 8.0);
  z.mirror_walls = zb.boolean("mirror_walls", z.mirror_walls);
  // A lone particle's radius is at least ZhuBridsonParams::kLoneRadius, whatever particle_radius.
  const double lone = ZhuBridsonParams::lone_radius_of(float(z.particle_radius));
  if (lone > z.radius - 0.5) {
    std::ostringstream why;
    why << "the field falls to zero over radius less the particle radius (a lone particle's at least "
        << ZhuBridsonParams::kLoneRadius << "), at least half a voxel";
    if (zb.has("particle_radius") && z.particle_radius > ZhuBridsonParams::kLoneRadius)
      zb.fail("particle_radius", zb.at("particle_radius"), "must be at most radius - 0.5: " + why.str());
    std::ostringstream os;
    os << "must be at least " << lone + 0.5 << ": " << why.str();
    zb.fail("radius", zb.at("radius"), os.str());
  }
  const ConfigReader a = r.child("anisotropy");
  a.only({"radius", "stretch", "smoothing", "min_neighbours", "mirror_walls"});
  AnisotropyConfig& an = c.anisotropy;
  an.radius = a.number("radius", an.radius, 0.5, 4.0);
  an.stretch = a.number("stretch", an.stretch, 1.0, 16.0);
  an.smoothing = a.number("smoothing", an.smoothing, 0.0, 1.0);
  an.min_neighbours = a.integer("min_neighbours", an.min_neighbours, 0, 1000);
  an.mirror_walls = a.boolean("mirror_walls", an.mirror_walls);
  return c;
}

}  // namespace sphray
