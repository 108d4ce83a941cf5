#include "config.h"

#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include "pbf_kernel.h"
#include "pbf_lattice.h"

namespace sphray {

int SphConfig::auto_boundary_layers() const { return int(std::ceil(support_radius() / spacing - 1e-9)); }

namespace {

// The sph keys that only the weakly compressible solver reads.
constexpr const char* kWcsphKeys[] = {"speed_of_sound", "smoothing_ratio", "kernel", "viscosity_alpha",
                                      "wall_viscosity_alpha", "density_diffusion", "boundary_layers"};

void read_wcsph_options(const ConfigReader& r, SphConfig& c) {
  if (r.has("speed_of_sound") && r.at("speed_of_sound").is_string()) {
    if (r.at("speed_of_sound") != "auto")
      r.fail("speed_of_sound", r.at("speed_of_sound"), "must be \"auto\" or a positive number [m/s]");
  } else {
    c.speed_of_sound = r.has("speed_of_sound") ? r.number("speed_of_sound", 0, 0, 1e5, false, true) : 0.0;
  }
  c.smoothing_ratio = r.number("smoothing_ratio", c.smoothing_ratio, 1.0, 3.0);
  c.kernel = r.string("kernel", "wendland_c2", {"wendland_c2", "cubic_spline"}) == "cubic_spline"
                 ? KernelType::CubicSpline
                 : KernelType::WendlandC2;
  c.viscosity_alpha = r.number("viscosity_alpha", c.viscosity_alpha, 0, 1);
  c.wall_viscosity_alpha = r.number("wall_viscosity_alpha", c.wall_viscosity_alpha, 0, 1);
  c.density_diffusion = r.number("density_diffusion", c.density_diffusion, 0, 1);
  if (r.has("boundary_layers") && !(r.at("boundary_layers").is_string() && r.at("boundary_layers") == "auto")) {
    const double l = r.number("boundary_layers", 0, 1, 8);
    if (l != std::floor(l)) r.fail("boundary_layers", r.at("boundary_layers"), "must be \"auto\" or an integer 1..8");
    c.boundary_layers = int(l);
  }
}

PbfConfig read_pbf_config(const ConfigReader& r) {
  r.only({"iterations", "tolerance", "support", "relaxation", "scorr_k", "scorr_dq", "scorr_n", "depth_error", "step_error", "max_correction", "xsph",
          "vorticity", "step_error_flow", "flow_speed", "wall_margin", "images", "rest_weights"});
  PbfConfig c;
  c.iterations = r.integer("iterations", c.iterations, 1, 100);
  c.tolerance = r.number("tolerance", c.tolerance, 0, 1);
  c.support = r.number("support", c.support, 1.5, 4.0);
  c.relaxation = r.number("relaxation", c.relaxation, 0, 100, false, true);
  c.scorr_k = r.number("scorr_k", c.scorr_k, 0, 1);
  c.scorr_dq = r.number("scorr_dq", c.scorr_dq, 0, 1, false, true);
  c.scorr_n = r.integer("scorr_n", c.scorr_n, 1, 8);
  const double push = scorr_surface_push(c.support, c.scorr_k, c.scorr_dq, c.scorr_n);
  if (push > kMaxScorrPush) {
    const char* key = r.has("scorr_dq") ? "scorr_dq" : r.has("scorr_n") ? "scorr_n" : "scorr_k";
    std::ostringstream os;
    os << "makes s_corr push a flat free surface by " << push << " spacings per iteration (pbf.scorr_k " << c.scorr_k
       << ", pbf.scorr_dq " << c.scorr_dq << ", pbf.scorr_n " << c.scorr_n << ", pbf.support " << c.support
       << "), above " << kMaxScorrPush
       << ": the surface would be thrown off. Lower pbf.scorr_k or pbf.scorr_dq (docs/method.md, \"s_corr\")";
    r.fail(key, r.at(key), os.str());
  }
  c.depth_error = r.number("depth_error", c.depth_error, 0, 1);
  c.step_error = r.number("step_error", c.step_error, 0, 1);
  c.step_error_flow = r.number("step_error_flow", c.step_error_flow, 0, 1);
  c.flow_speed = r.number("flow_speed", c.flow_speed, 0, 100);
  c.max_correction = r.number("max_correction", c.max_correction, 0, 10);
  c.wall_margin = r.number("wall_margin", c.wall_margin, 0, 0.5);
  c.mirrored_images = r.string("images", c.mirrored_images ? "mirrored" : "static", {"mirrored", "static"}) == "mirrored";
  c.rest_chebyshev =
      r.string("rest_weights", c.rest_chebyshev ? "chebyshev" : "uniform", {"chebyshev", "uniform"}) == "chebyshev";
  c.xsph = r.number("xsph", c.xsph, 0, 1);
  c.vorticity = r.number("vorticity", c.vorticity, 0, 100);
  return c;
}

// PBF's kernels are single precision (sph/pbf_kernel.h), and poly6's
// constant, 315 / (64 pi s^9), exceeds the largest float below a support of
// 55 um: every density would be infinite. Refused by sph.spacing, naming the
// smallest spacing that fits at the scene's pbf.support.
void refuse_pbf_scale(const ConfigReader& r, const SphConfig& c) {
  const double float_max = double(std::numeric_limits<float>::max());
  const double s = c.pbf.support * c.spacing;
  const double poly6 = PbfKernel<double>::make(s).poly6;
  if (poly6 < float_max) return;
  const double s_min = s * std::pow(poly6 / float_max, 1.0 / 9.0);  // poly6 falls as s^-9
  std::ostringstream os;
  os << "gives PBF a support of " << s << " m (pbf.support " << c.pbf.support
     << " spacings), where its single-precision density kernel overflows (poly6, 315 / (64 pi s^9), above "
     << float_max << " below a support of " << s_min << " m); PBF needs sph.spacing >= " << s_min / c.pbf.support
     << " m at this support";
  r.fail("spacing", r.has("spacing") ? r.at("spacing") : ConfigReader::json(c.spacing), os.str());
}

DfsphConfig read_dfsph_config(const ConfigReader& r) {
  r.only({"tolerance", "divergence_tolerance", "min_iterations", "max_iterations", "max_divergence_iterations",
          "kernel", "support", "viscosity", "wall_margin"});
  DfsphConfig c;
  c.tolerance = r.number("tolerance", c.tolerance, 0, 1, false, true);
  c.divergence_tolerance = r.number("divergence_tolerance", c.divergence_tolerance, 0, 1, false, true);
  c.min_iterations = r.integer("min_iterations", c.min_iterations, 1, 1000);
  c.max_iterations = r.integer("max_iterations", c.max_iterations, 1, 1000);
  if (c.max_iterations < c.min_iterations) {
    const char* key = r.has("max_iterations") ? "max_iterations" : "min_iterations";
    r.fail(key, r.at(key), "leaves dfsph.max_iterations (" + std::to_string(c.max_iterations) +
                               ") below dfsph.min_iterations (" + std::to_string(c.min_iterations) + ")");
  }
  c.max_divergence_iterations = r.integer("max_divergence_iterations", c.max_divergence_iterations, 1, 1000);
  c.wall_margin = r.number("wall_margin", c.wall_margin, 0, 0.5);
  c.kernel = r.string("kernel", "cubic_spline", {"cubic_spline", "wendland_c2"}) == "wendland_c2"
                 ? KernelType::WendlandC2
                 : KernelType::CubicSpline;
  c.support = r.number("support", c.support, 1.5, 4.0);
  if (r.has("viscosity") && !(r.at("viscosity").is_string() && r.at("viscosity") == "auto"))
    c.viscosity = r.number("viscosity", 0, 0, 10);
  return c;
}

// Options that only the weakly compressible solver reads, refused by name
// under another solver.
void refuse_wcsph_options(const ConfigReader& r, SolverKind solver) {
  const std::string name = solver_name(solver);
  for (const char* key : kWcsphKeys)
    if (r.has(key))
      r.fail(key, r.at(key), "is an option of the wcsph solver, but sph.solver is \"" + name + "\" (remove it; the " +
                                 name + " solver's options are in the \"" + name + "\" section, docs/scenes.md)");
}

}  // namespace

SphConfig read_sph_config(const ConfigReader& r, const ConfigReader& pbf, const ConfigReader& dfsph) {
  r.only({"solver", "spacing", "rest_density", "speed_of_sound", "smoothing_ratio", "kernel", "viscosity_alpha",
          "wall_viscosity_alpha", "density_diffusion", "cfl", "boundary_layers", "presence"});
  SphConfig c;
  const std::string solver = r.string("solver", "wcsph", {"wcsph", "pbf", "dfsph"});
  c.solver = solver == "pbf" ? SolverKind::Pbf : solver == "dfsph" ? SolverKind::Dfsph : SolverKind::Wcsph;
  c.spacing = r.number("spacing", c.spacing, 0, 1e3, true, true);
  c.rest_density = r.number("rest_density", c.rest_density, 0, 1e5, false, true);
  if (c.solver == SolverKind::Pbf) {
    refuse_wcsph_options(r, c.solver);
    // A CFL above 1 is allowed for studies of the step size (docs/validation.md).
    c.cfl = r.number("cfl", SphConfig::kPbfCfl, 0, 10, false, true);
    c.pbf = read_pbf_config(pbf);
    refuse_pbf_scale(r, c);
  } else if (c.solver == SolverKind::Dfsph) {
    refuse_wcsph_options(r, c.solver);
    c.cfl = r.number("cfl", SphConfig::kDfsphCfl, 0, 10, false, true);
    c.dfsph = read_dfsph_config(dfsph);
  } else {
    read_wcsph_options(r, c);
    c.cfl = r.number("cfl", SphConfig::kWcsphCfl, 0, 1, false, true);
  }
  c.presence = r.boolean("presence", c.presence);
  return c;
}

}  // namespace sphray
