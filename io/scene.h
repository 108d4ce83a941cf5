// A scene: the tank, the fluid blocks, gravity and run settings, and the
// sections of the stages (sph, field, render), read from JSON, overridden by
// --set key.path=value, validated once and then immutable. The scene reader
// reads its own sections and hands each stage's to that stage's reader. Every
// bad value is a SceneError naming file, key and value.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/config_reader.h"
#include "core/vec.h"
#include "field/config.h"
#include "mesh/mesh.h"
#include "render/render_settings.h"
#include "sph/config.h"
#include "sph/obstacles.h"
#include "sph/skin_params.h"
#include "sph/eos.h"

namespace sphray {

// Blocks may overlap: their union is filled once (setup.cpp).
struct FluidBlock {
  Box box;
  Vec3d velocity{0, 0, 0};
};

// A triangle mesh in the tank, static or in a prescribed oscillation: the
// liquid flows around it (sph/obstacles.h; WCSPH's wall particles fill a
// static one's skin), the raycaster draws it.
struct Obstacle {
  std::string path;     // the mesh file, resolved against the scene's folder
  Placement placement;  // as given
  TriangleMesh mesh;    // placed: world coordinates at t = 0, outward winding
  Motion motion;        // "motion"; omega 0: static
  bool has_skin = false;  // "skin": waves on its surface (sph/skin.h)
  SkinParams skin;
  SphereEmbedding skin_embedding;  // the mesh mapped onto the sphere (mesh/skin_map.h), when it has a skin
};

// A water-height gauge: the liquid's height above the tank floor on the
// vertical line through (x, y), written per output frame to the metrics CSV
// (io/metrics.h, water_height).
struct Gauge {
  std::string name;
  double x = 0, y = 0;
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
  std::vector<Obstacle> obstacles;  // "obstacles": [{"mesh", "scale", "rotate", "translate"}]
  std::vector<Gauge> gauges;        // "gauges": [{"name", "at": [x, y]}]
  Vec3d gravity{0, 0, -kStandardGravity};

  SphConfig sph;        // the "sph" section, and "pbf" or "dfsph" when it runs that solver (sph/config.h)
  FieldConfig field;    // the density field (field/config.h); built only when a later stage uses it
  RenderSettings render;  // the raycaster (render/render_settings.h); used only by renders

  struct Export {
    int gzip = 0;  // HDF5 export: deflate level 0 (off) .. 9
    // A run over several ranks: "auto" (every rank writes its rows with
    // parallel HDF5 where the build has it and the export allows it, else
    // rank 0 writes), "rank0", "parallel" (refused where it cannot).
    std::string writer = "auto";
  } export_;

  struct Run {
    double end_time = 1.0;         // [s]
    double output_interval = 0.01; // [s]
    double min_dt = 1e-8;          // [s] a smaller step is an error
    double max_dt = 1e-3;          // [s] (PBF, DFSPH: kFlowMaxDt)
    static constexpr double kFlowMaxDt = 5e-3;
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

}  // namespace sphray
