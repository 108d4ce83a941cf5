// `sphray bench sim|field|frame|render|surface|mesh|skin`: the benchmarks (bench/), their
// tables on stdout and, with --json, their records.
#include <iostream>

#include "bench/field.h"
#include "bench/frame.h"
#include "bench/mesh.h"
#include "bench/skin.h"
#include "bench/sim.h"
#include "bench/surface.h"
#include "cli.h"
#include "commands.h"
#include "io/scene.h"
#include "pipeline/pipeline.h"
#include "sphray_builtin_scenes.h"

namespace sphray::cli {

namespace {

// What every benchmark command takes besides its own options.
struct Common {
  std::string backend = "auto", sizes, json;
};

void add_common(CLI::App* c, Common& o, const std::string& sizes_help) {
  c->add_option("--backend", o.backend, "auto | cpu | cuda");
  if (!sizes_help.empty()) c->add_option("--sizes", o.sizes, sizes_help);
  c->add_option("--json", o.json, "write results as JSON");
}

// Opens --json before the benchmark (a bad path fails at once), runs it and
// writes its record.
template <class Run>
void run_bench(const Common& o, Run run) {
  std::ofstream jf;
  if (!o.json.empty()) jf = open_output("--json", o.json);
  const Backend b = choose_backend(o.backend, std::cout);
  const nlohmann::json j = run(b);
  if (jf.is_open()) write_json(jf, j, "--json", o.json);
}

void add_sim(CLI::App* bench, int& exit_code) {
  struct Args {
    Common c;
    std::string scene;
    BenchSimOptions opt;
  };
  auto a = std::make_shared<Args>();
  auto* s = bench->add_subcommand("sim", "ms per SPH step by stage, with and without presence");
  s->add_option("--scene", a->scene,
                "dam-break scene whose spacing is scaled to each size (default: scenes/bench/dam_break.json, "
                "built in)");
  add_common(s, a->c, "fluid particle counts (default 125k,1M,4M on CUDA, 8k,27k on CPU)");
  s->add_option("--warmup", a->opt.warmup, "warm-up steps")->check(CLI::Range(0, 100000));
  s->add_option("--steps", a->opt.steps, "measured steps")->check(CLI::Range(1, 100000));
  s->add_option("--set", a->opt.overrides, "override a scene value for every size, e.g. --set sph.smoothing_ratio=1.3");
  s->add_flag("--kernels", a->opt.kernels, "also time every named launch (ms per step by name, over further steps)");
  s->add_option("--solvers", a->opt.solvers, "each of these solvers in turn, e.g. wcsph,pbf,dfsph (default: the scene's)")
      ->delimiter(',');
  s->add_option("--from", a->opt.from, "simulated seconds to advance (untimed) before the warm-up, so that the "
                                       "steps are those of the flow (e.g. 0.3 for the dam break)")
      ->check(CLI::Range(0.0, 100.0));
  s->callback([a, &exit_code] {
    run_bench(a->c, [&](Backend b) {
      a->opt.sizes = parse_sizes(!a->c.sizes.empty() ? a->c.sizes : b == Backend::Cuda ? "125k,1M,4M" : "8k,27k");
      // The default scene is compiled in, so that the benchmark runs from any directory.
      const auto rows = a->scene.empty() ? bench_sim(builtin::bench_dam_break, "scenes/bench/dam_break.json (built in)",
                                                     b, a->opt, std::cout)
                                         : bench_sim(read_scene_text(a->scene), a->scene, b, a->opt, std::cout);
      print_table(rows, std::cout);
      return to_json(rows, b, a->opt);
    });
    exit_code = 0;
  });
}

void add_mesh(CLI::App* bench, int& exit_code) {
  struct Args {
    Common c;
    BenchMeshOptions opt;
  };
  auto a = std::make_shared<Args>();
  auto* m = bench->add_subcommand("mesh", "obstacle BVH build and refit, and the collision pass, by triangle count");
  add_common(m, a->c, "");
  m->add_option("--levels", a->opt.levels, "icosphere subdivisions (20 * 4^level triangles), e.g. 4,6,8")
      ->delimiter(',')
      ->check(CLI::Range(0, 9));
  m->add_option("--particles", a->opt.particles, "particle paths per collision pass")->check(CLI::Range(1, 100000000));
  m->add_option("--warmup", a->opt.warmup, "warm-up runs of each")->check(CLI::Range(0, 1000));
  m->add_option("--frames", a->opt.frames, "measured runs of each")->check(CLI::Range(1, 10000));
  m->callback([a, &exit_code] {
    run_bench(a->c, [&](Backend b) {
      const auto rows = bench_mesh(b, a->opt, std::cout);
      print_table(rows, std::cout);
      return to_json(rows, b, a->opt);
    });
    exit_code = 0;
  });
}

void add_skin(CLI::App* bench, int& exit_code) {
  struct Args {
    Common c;
    BenchSkinOptions opt;
  };
  auto a = std::make_shared<Args>();
  auto* k = bench->add_subcommand("skin", "waves on an obstacle's skin: an impulse's speed by direction, per cube-map "
                                          "resolution and stencil, and the cost of a substep");
  add_common(k, a->c, "");
  k->add_option("--resolutions", a->opt.resolutions, "texels along a cube edge, e.g. 24,48,96")
      ->delimiter(',')
      ->check(CLI::Range(8, 512));
  k->add_option("--warmup", a->opt.warmup, "warm-up substeps")->check(CLI::Range(0, 1000));
  k->add_option("--frames", a->opt.frames, "measured substeps")->check(CLI::Range(1, 10000));
  k->callback([a, &exit_code] {
    run_bench(a->c, [&](Backend b) {
      const auto rows = bench_skin(b, a->opt, std::cout);
      print_table(rows, std::cout);
      return to_json(rows, b, a->opt);
    });
    exit_code = 0;
  });
}

void add_field(CLI::App* bench, int& exit_code) {
  struct Args {
    Common c;
    BenchFieldOptions opt;
  };
  auto a = std::make_shared<Args>();
  auto* f = bench->add_subcommand("field", "naive vs presence vs gather density-field builders on a collapsed dam break");
  add_common(f, a->c, "fluid particle counts (default 8k,27k,64k,125k,1M,4M on CUDA, 8k,27k on CPU)");
  f->add_option("--volume", a->opt.volume, "volume edge in voxels (default 64 up to 200k particles, else 256)")
      ->check(CLI::Range(8, 1024));
  f->add_option("--warmup", a->opt.warmup, "warm-up builds per builder")->check(CLI::Range(0, 10000));
  f->add_option("--frames", a->opt.frames, "measured builds per builder")->check(CLI::Range(1, 100000));
  f->add_option("--collapse", a->opt.collapse, "build at T = t sqrt(2g/a) (column collapsed)")
      ->check(CLI::Range(0.0, 100.0));
  f->add_option("--set", a->opt.overrides, "override a value of the generated scene, e.g. --set field.clip=2");
  f->add_flag("--kernels", a->opt.kernels, "also time every named launch (ms per build by name, over further builds)");
  f->callback([a, &exit_code] {
    run_bench(a->c, [&](Backend b) {
      a->opt.sizes = parse_sizes(!a->c.sizes.empty() ? a->c.sizes
                                 : b == Backend::Cuda  ? "8k,27k,64k,125k,1M,4M"
                                                       : "8k,27k");
      const auto rows = bench_field(b, a->opt, std::cout);
      print_table(rows, std::cout);
      return to_json(rows, b, a->opt);
    });
    exit_code = 0;
  });
}

void add_frame(CLI::App* bench, int& exit_code) {
  struct Args {
    Common c;
    BenchFrameOptions opt;
  };
  auto a = std::make_shared<Args>();
  auto* f = bench->add_subcommand("frame", "whole frames: SPH substeps + field + raycast, per-stage medians");
  add_common(f, a->c, "fluid particle counts (default 125k,1M on CUDA, 8k on CPU)");
  BenchFrameOptions& o = a->opt;
  f->add_option("--width", o.width, "image width")->check(CLI::Range(16, 8192));
  f->add_option("--height", o.height, "image height")->check(CLI::Range(16, 8192));
  f->add_option("--interfaces", o.interfaces, "interfaces per ray")->check(CLI::Range(1, 8));
  f->add_option("--substeps", o.substeps, "SPH steps per frame")->check(CLI::Range(1, 1000));
  f->add_flag("--realtime", o.realtime,
              "real-time playback: each frame advances by the previous frame's wall time (at most 1/30 s)");
  f->add_option("--builder", o.builder, "naive | presence | gather (default: the scene's, presence; gather for zhu_bridson)");
  f->add_option("--warmup", o.warmup, "warm-up frames")->check(CLI::Range(0, 10000));
  f->add_option("--frames", o.frames, "measured frames")->check(CLI::Range(1, 100000));
  f->add_option("--collapse", o.collapse, "start at T = t sqrt(2g/a)")->check(CLI::Range(0.0, 100.0));
  f->add_option("--png-dir", o.png_dir, "write each size's last frame here");
  f->add_option("--set", o.overrides, "override a value of the generated scene, e.g. --set render.step=0.25");
  f->callback([a, &exit_code] {
    run_bench(a->c, [&](Backend b) {
      a->opt.sizes = parse_sizes(!a->c.sizes.empty() ? a->c.sizes : b == Backend::Cuda ? "125k,1M" : "8k");
      if (!a->opt.builder.empty()) parse_field_kind(a->opt.builder);  // a bad name fails before the simulation
      const auto rows = bench_frame(b, a->opt, std::cout);
      print_table(rows, std::cout);
      return to_json(rows, b, a->opt);
    });
    exit_code = 0;
  });
}

void add_render(CLI::App* bench, int& exit_code) {
  struct Args {
    Common c;
    std::string size;
    BenchRenderOptions opt;
  };
  auto a = std::make_shared<Args>();
  auto* r = bench->add_subcommand("render", "each render method's image error (PSNR, SSIM vs a fine raycast reference) "
                                            "against render time");
  add_common(r, a->c, "");
  BenchRenderOptions& o = a->opt;
  r->add_option("--size", a->size, "fluid particle count (default 125k on CUDA, 8k on CPU)");
  r->add_option("--width", o.width, "image width")->check(CLI::Range(16, 8192));
  r->add_option("--height", o.height, "image height")->check(CLI::Range(16, 8192));
  r->add_option("--scene", o.scene, "dam_break (the collapse at T = --collapse) or pool (a still pool)")
      ->check(CLI::IsMember({"dam_break", "pool"}));
  r->add_option("--collapse", o.collapse, "dam_break: render at T = t sqrt(2g/a)")->check(CLI::Range(0.0, 100.0));
  r->add_option("--methods", o.methods, "render methods to compare: raycast, screen_space, slices")
      ->delimiter(',')
      ->check(CLI::IsMember({"raycast", "screen_space", "slices"}));
  r->add_option("--filter-iterations", o.filter_iterations, "screen_space: bilateral filter passes to compare")
      ->delimiter(',')
      ->check(CLI::Range(0, 64));
  r->add_option("--slices", o.slices, "slices: slice counts to compare")->delimiter(',')->check(CLI::Range(8, 4096));
  r->add_option("--steps", o.steps, "raycast: march steps [voxels] to compare")
      ->delimiter(',')
      ->check(CLI::Range(0.001, 0.5));
  r->add_option("--interfaces", o.interfaces, "raycast: interface counts to compare")
      ->delimiter(',')
      ->check(CLI::Range(1, 8));
  r->add_option("--reference-step", o.reference_step, "reference march step [voxels]")->check(CLI::Range(0.001, 0.5));
  r->add_option("--warmup", o.warmup, "warm-up renders")->check(CLI::Range(0, 10000));
  r->add_option("--frames", o.frames, "measured renders")->check(CLI::Range(1, 100000));
  r->add_option("--budgets", o.budgets,
                "branch budgets to compare, e.g. 0,4,8 (interfaces per pixel after the first path; 0: reflections off)")
      ->delimiter(',')
      ->check(CLI::Range(0, 64));
  r->add_option("--min-weight", o.min_weight, "with reflections, branches weaker than this take the environment")
      ->check(CLI::Range(0.0, 1.0));
  r->add_option("--png-dir", o.png_dir, "write the reference and each method's image at the scene's settings here");
  r->add_option("--set", o.overrides, "override a value of the generated scene");
  r->callback([a, &exit_code] {
    run_bench(a->c, [&](Backend b) {
      const auto sizes = parse_sizes(!a->size.empty() ? a->size : b == Backend::Cuda ? "125k" : "8k");
      if (sizes.size() != 1) throw std::runtime_error("--size: one particle count");
      a->opt.particles = sizes[0];
      const auto rows = bench_render(b, a->opt, std::cout);
      print_table(rows, std::cout);
      return to_json(rows, b, a->opt);
    });
    exit_code = 0;
  });
}

void add_surface(CLI::App* bench, int& exit_code) {
  struct Args {
    Common c;
    BenchSurfaceOptions opt;
  };
  auto a = std::make_shared<Args>();
  auto* f = bench->add_subcommand("surface", "surface error of each field kernel and refine level against analytic "
                                             "surfaces (pool, ball, sheet), with build times");
  add_common(f, a->c, "");
  f->add_option("--cells", a->opt.cells, "pool width in particles (default 64 on CUDA, 24 on CPU)")
      ->check(CLI::Range(12, 512));
  f->add_option("--layers", a->opt.layers, "pool depth in particle layers (default half its width)")
      ->check(CLI::Range(4, 508));
  f->add_option("--settle", a->opt.settle, "seconds the pool settles under gravity")->check(CLI::Range(0.0, 10.0));
  f->add_option("--jitter", a->opt.jitter, "pool and ball start this many spacings off the lattice, at most")
      ->check(CLI::Range(0.0, 0.45));
  f->add_option("--warmup", a->opt.warmup, "warm-up builds per setting")->check(CLI::Range(0, 10000));
  f->add_option("--frames", a->opt.frames, "measured builds per setting")->check(CLI::Range(1, 100000));
  f->add_option("--set", a->opt.overrides, "override a value of the generated scene, e.g. --set field.anisotropy.stretch=3");
  f->callback([a, &exit_code] {
    run_bench(a->c, [&](Backend b) {
      const auto rows = bench_surface(b, a->opt, std::cout);
      print_table(rows, std::cout);
      return to_json(rows, b, a->opt);
    });
    exit_code = 0;
  });
}

}  // namespace

CLI::App* add_bench_command(CLI::App& app, int& exit_code) {
  auto* bench = app.add_subcommand("bench", "benchmarks");
  bench->require_subcommand(1);
  add_sim(bench, exit_code);
  add_field(bench, exit_code);
  add_frame(bench, exit_code);
  add_render(bench, exit_code);
  add_surface(bench, exit_code);
  add_mesh(bench, exit_code);
  add_skin(bench, exit_code);
  return bench;
}

}  // namespace sphray::cli
