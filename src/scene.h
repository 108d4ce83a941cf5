// A scene: the tank, the fluid blocks, gravity, SPH and run settings, read
// from JSON, overridden by --set key.path=value, validated once and then
// immutable. Every bad value is a SceneError naming file, key and value.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../cuda/common/vec.h"
#include "../cuda/sph/kernel.h"
#include "render_settings.h"

namespace sphray {

struct SceneError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Box {
  Vec3d min, max;
};

// Blocks may overlap: their union is filled once (setup.cpp).
struct FluidBlock {
  Box box;
  Vec3d velocity{0, 0, 0};
};

struct Scene {
  std::string file;     // where it came from
  nlohmann::json json;  // the scene as it runs (after --set), for provenance
  std::string name;

  Box tank;
  bool open_top = false;
  // Faces without wall friction, from "-x", "+x", "-y", "+y", "-z", "+z"
  // (e.g. the side walls of a quasi-2D slab). Other walls are viscous.
  bool free_slip[6] = {false, false, false, false, false, false};
  std::vector<FluidBlock> fluid;
  Vec3d gravity{0, 0, -9.81};

  struct Sph {
    double spacing = 0;          // dx [m]
    double rest_density = 1000;  // [kg/m^3]
    double speed_of_sound = 0;   // [m/s], 0 = auto
    double smoothing_ratio = 2.0;  // h / dx (DualSPHysics uses 1.2 sqrt(3) = 2.08 in 3D)
    KernelType kernel = KernelType::WendlandC2;
    double viscosity_alpha = 0.02;
    double wall_viscosity_alpha = -1;  // against viscous walls; < 0: viscosity_alpha
    double density_diffusion = 0.1;
    double cfl = 0.25;
    int boundary_layers = 0;  // 0 = auto: enough to cover the support radius
    bool presence = false;
  } sph;

  // The density field (docs/field.md). Built only when a later stage uses it.
  struct Field {
    bool given = false;              // the scene has a "field" section
    std::string builder = "presence";  // "naive" | "presence" | "gather"
    int refine = 2;                  // voxels per SPH cell edge = 2^refine
    double radius = 2.0;             // influence radius R [voxels]
    double core = 0.5;               // finite core of the inverse-square falloff [voxels]
    double clip = 4.0;               // saturation value as a multiple of the iso value
    double min_extent = 1.0;         // presence builder: extent toward a fully surrounded side [voxels]
    double shrink_from = 0.5;        // presence builder: a side keeps its full extent up to this presence
    double full_fraction = 0.9;      // presence coarse fill (refine > 0): share of (cell/dx)^3 that fills a cell
    std::string full_value = "clip";  // ... and the value it gets: "clip" (saturated) or "coarse"
  } field;

  // The raycaster (docs/rendering.md). Used only by renders (--frames-dir, render, view).
  RenderSettings render;

  struct Export {
    int gzip = 0;  // HDF5 export: deflate level 0 (off) .. 9
  } export_;

  struct Run {
    double end_time = 1.0;         // [s]
    double output_interval = 0.01; // [s]
    double min_dt = 1e-8;          // [s] a smaller step is an error
    double max_dt = 1e-3;          // [s]
  } run;
};

// Parses JSON text (file names the source in messages), applies overrides
// ("key.path=value", value as JSON or else as a string) and validates.
Scene parse_scene(const std::string& text, const std::string& file, const std::vector<std::string>& overrides = {});
Scene load_scene(const std::string& path, const std::vector<std::string>& overrides = {});
// The text of a scene file, with load_scene's messages for a path that is a
// directory, unreadable, or an HDF5 export.
std::string read_scene_text(const std::string& path);

// Whether `head` (a file's first bytes) starts with the HDF5 signature (a
// file of sphray run --export at offset 0, where sphray writes it).
bool is_hdf5_signature(const std::string& head);

// Unit vector "up" (against gravity); +z when there is no gravity.
Vec3d up_of(const Scene& s);

// The highest point of a box along `up`.
double box_top(const Box& b, Vec3d up);

// The flow speed a scene can be expected to reach: sqrt(g H), H the height of
// its liquid's top above the tank floor along gravity (standard gravity when
// there is none; a dropped block counts its fall), or its fastest initial
// velocity if that is more. An explicit speed of sound below it is an error
// (parse_scene): the flow would be supersonic and a weakly compressible fluid
// meaningless.
double expected_flow_speed(const Scene& s);

// The automatic speed of sound: 10x expected_flow_speed, which keeps density
// variations near 1% (Monaghan 1994).
double auto_speed_of_sound(const Scene& s);

// The automatic number of wall particle layers: enough to cover the kernel's
// support (2h / dx, rounded up), so that a particle at a wall face finds its
// kernel full. Fewer (sph.boundary_layers) leave part of it empty near walls.
int auto_boundary_layers(const Scene& s);

}  // namespace sphray
