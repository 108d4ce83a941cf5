// `sphray bench frame`: whole frames of the dam break, headless: SPH substeps,
// the density field and the raycast, each timed with device events after a
// warm-up, medians over the measured frames (and the frame's wall time).
// `sphray bench render`: each render method's image error (PSNR and SSIM
// against a reference raycast from the naive field with a very small step and
// every branch traced to 8 interfaces) against its run time: the raycaster
// over step size, interfaces, the reflected branch's budget and field
// builder; screen-space refraction over its filter passes; slices over their
// count.
#pragma once

#include <iosfwd>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "field/field.h"
#include "sph/solver.h"

namespace sphray {

struct BenchFrameOptions {
  std::vector<size_t> sizes;  // target fluid particle counts (bench_field_scene: 64^3 up to 200k, else 256^3)
  int width = 1920, height = 1080;
  int interfaces = 4;
  int substeps = 5;           // SPH steps per frame (unless realtime)
  // Real-time playback (as the viewer's default): each frame advances the
  // simulation by the previous frame's wall time, at most max_sim_per_frame,
  // in steps taking at most that much wall time.
  bool realtime = false;
  double max_sim_per_frame = 1.0 / 30.0;
  std::string builder;         // naive, presence or gather; empty: the scene's (presence; gather for zhu_bridson)
  int warmup = 5;
  int frames = 30;
  double collapse = 2.5;      // frames start at T = t sqrt(2g/a) = collapse
  std::string png_dir;        // write the last frame of each size here (empty: none)
  std::vector<std::string> overrides;
};

struct BenchFrameRow {
  size_t particles = 0;
  int nx = 0, ny = 0, nz = 0;
  int width = 0, height = 0, interfaces = 0, substeps = 0;
  std::string builder;
  double sim_ms = 0, field_ms = 0, render_ms = 0, total_ms = 0, wall_ms = 0;  // medians per frame
  double fps = 0;  // 1000 / wall_ms
  bool realtime = false;
  double steps = 0;            // median SPH steps per frame
  double realtime_factor = 0;  // simulated seconds per wall second over the measured frames
};

std::vector<BenchFrameRow> bench_frame(Backend b, const BenchFrameOptions& opt, std::ostream& log);
nlohmann::json to_json(const std::vector<BenchFrameRow>& rows, Backend b, const BenchFrameOptions& opt);
void print_table(const std::vector<BenchFrameRow>& rows, std::ostream& out);

struct BenchRenderOptions {
  size_t particles = 125000;
  std::string scene = "dam_break";  // dam_break (the collapse at T = collapse) or pool (a still pool, the same particles)
  int width = 960, height = 540;
  double reference_step = 0.05;  // voxels
  std::vector<std::string> methods{"raycast", "screen_space", "slices"};
  // raycast: every builder x step x interfaces x budget
  std::vector<double> steps{0.5, 0.25};
  std::vector<int> interfaces{2, 4, 8};
  std::vector<int> budgets{0, 4, 8, 16};  // interfaces per pixel after the first path; 0: reflected branch not traced
  double min_weight = 1.0 / 256;           // with reflections: weaker branches take the environment
  std::vector<int> filter_iterations{0, 4, 20};  // screen_space, at the scene's filter width
  std::vector<int> slices{128, 256, 512};        // slices, presence field, the scene's other settings
  int warmup = 3;
  int frames = 10;
  double collapse = 2.5;
  std::string png_dir;  // the reference and each method's image at the scene's settings
  std::vector<std::string> overrides;
};

struct BenchRenderRow {
  std::string method;                  // raycast, screen_space, slices
  std::string builder;                 // the field's ("" for screen_space)
  double step = 0;                     // raycast march step [voxels]
  int interfaces = 0;
  int budget = 0;                      // 0: reflections off
  int filter_iterations = 0;           // screen_space
  int slices = 0;                      // slices
  double render_ms = 0, field_ms = 0;  // medians (screen_space builds no field)
  std::vector<std::pair<std::string, double>> stages_ms;  // the render's stages, medians
  double psnr_db = 0, ssim = 0;        // against the reference
};

std::vector<BenchRenderRow> bench_render(Backend b, const BenchRenderOptions& opt, std::ostream& log);
nlohmann::json to_json(const std::vector<BenchRenderRow>& rows, Backend b, const BenchRenderOptions& opt);
void print_table(const std::vector<BenchRenderRow>& rows, std::ostream& out);

}  // namespace sphray
