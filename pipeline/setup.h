// A validated scene resolved once for the stages the pipeline makes: the SPH
// parameters of its kernels, its particle and grid counts, its memory
// estimate; and from it the solver's initial state (the fluid lattice at
// hydrostatic density, the wall particles, the grid) and the field's volume.
#pragma once

#include <cstddef>

#include "field/field.h"
#include "render/render.h"
#include "sph/skin.h"
#include "io/frames_h5.h"
#include "io/scene.h"
#include "sph/solver.h"

namespace sphray {

struct SceneSize {
  size_t fluid = 0, boundary = 0, cells = 0;
  size_t step_cells = 0;    // of the grid a step sorts by: `cells`, or 8 x under PBF (GridGeom::halved)
  int boundary_layers = 0;  // the tank's wall layers (WCSPH; 0: PBF, DFSPH)
  int mesh_layers = 0;      // the obstacles' wall layers (SphConfig::mesh_wall_layers)
  GridGeom grid{};
  size_t bytes = 0;  // estimated memory of the solver's buffers: fluid * per_fluid + fixed
  size_t per_fluid = 0;  // of it, per fluid particle
};

// A scene with what every stage derives from it, computed once.
struct ResolvedScene {
  Scene scene;
  SphParams params;  // make_params
  PbfParams pbf;     // make_pbf_params, when the scene runs PBF
  DfsphParams dfsph; // make_dfsph_params, when the scene runs DFSPH
  SceneSize size;    // measure_scene
};
ResolvedScene resolve_scene(const Scene& s);

SphParams make_params(const Scene& s);
// A placed mesh as the solver and the renderer take it.
MeshInput mesh_input(const TriangleMesh& m);
std::vector<MeshInput> obstacle_meshes(const Scene& s);  // every obstacle's
std::vector<SkinInput> skin_inputs(const Scene& s);      // every skinned obstacle's
// The meshes a renderer draws for a run of `solver`: the scene's
// (obstacle_meshes), a skinned one replaced by its skin's finer surface
// (sph/skin.h), whose vertices show_skins then moves before each frame.
std::vector<MeshInput> drawn_obstacles(std::vector<MeshInput> meshes, const std::vector<SkinGeometry>& skins);
std::vector<MeshInput> drawn_obstacles(std::vector<MeshInput> meshes, const Solver& solver);
// Hands the renderer each skin's surface displaced by its waves now.
void show_skins(const Solver& solver, Renderer& renderer);
// One presence lobe (sph/interaction.h) of a particle inside a full cubic
// lattice of spacing dx: the value that presence is normalised by.
double presence_lobe_on_lattice(const SmoothingKernel<double>& k, double dx);
// The PBF solver's constants from the scene's "pbf" section, with the
// particle volume and the constraint's scale computed on a full lattice.
PbfParams make_pbf_params(const Scene& s);
// The DFSPH solver's constants from the scene's "dfsph" section, with the
// particle volume computed on a full lattice and the automatic viscosity.
DfsphParams make_dfsph_params(const Scene& s);
// dfsph.viscosity "auto": the kinematic viscosity that WCSPH's default
// artificial viscosity amounts to in this scene, alpha h c0 / 10 [m^2/s].
double auto_dfsph_viscosity(const Scene& s);
SceneSize measure_scene(const Scene& s);  // counts only; generates nothing
// `resume`: the last frame of an earlier run's export (--resume), whose
// particles, time and step the run starts from; it needs velocity and
// density (std::runtime_error naming what is missing or does not match).
SolverInput make_solver_input(const ResolvedScene& r, PresenceMode presence, const Frame* resume = nullptr);
// [m] The anisotropic field's neighbourhood radius when the solver's own
// neighbour loop can sum its covariance (WCSPH, radius within its support:
// SolverInput::covariance_radius), else 0 (the field builder's own pass).
float pair_loop_covariance_radius(const Scene& s);
// Whether the step that reaches a frame must run the solver's neighbour loop
// with presence for a field built by `builder` with or without ellipsoids:
// for the presence builder, and for ellipsoids where that step also sums
// their covariance (pair_loop_covariance_radius; the field's own neighbour
// pass is then skipped).
bool field_needs_presence_step(const Scene& s, FieldKind builder, bool anisotropic);

// The volume over the SPH grid cells that overlap the tank, and the falloff,
// from the scene's "field" section (defaults when it has none).
FieldSetup make_field_setup(const ResolvedScene& r);

// Throws SceneError when the scene (with its density field when `field`)
// would need more memory than `backend` has free.
// What one rank of a run over several holds (dist/): the fluid particles of
// its slab with its ghosts, and on rank 0 with frames or a field the whole
// run's particles besides (the frame view) and the field.
struct RankShare {
  int rank = 0, ranks = 1;
  size_t fluid = 0;
  bool whole_view = false;
  int ranks_on_node = 1;  // on the CPU backend they share the node's memory
  bool even = false;      // fluid is an even share (before the slabs are cut), not the slab's count
};
// Refuses (SceneError) a scene whose buffers would not fit the backend's free
// memory, or that sphray cannot index; with `share`, the buffers of that rank.
void check_fits(const ResolvedScene& r, Backend backend, bool field = false, const RankShare* share = nullptr);

// A scene sized for a GPU on the CPU backend: above kCpuLargeScene fluid
// particles the note names the sph.spacing that gives about
// kCpuSceneTarget (the README's main job falls back to a spacing that gives
// 22,880 particles on the CPU); "" on the GPU or for a smaller scene.
// `sphray run` and `sphray view` print it at the start.
constexpr size_t kCpuLargeScene = 200000, kCpuSceneTarget = 25000;
std::string cpu_scale_note(const ResolvedScene& r, Backend backend);

}  // namespace sphray
