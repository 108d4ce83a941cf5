#include "config.h"

#include <cmath>

namespace sphray {

int SphConfig::auto_boundary_layers() const { return int(std::ceil(support_radius() / spacing - 1e-9)); }

SphConfig read_sph_config(const ConfigReader& r) {
  r.only({"spacing", "rest_density", "speed_of_sound", "smoothing_ratio", "kernel", "viscosity_alpha",
          "wall_viscosity_alpha", "density_diffusion", "cfl", "boundary_layers", "presence"});
  SphConfig c;
  c.spacing = r.number("spacing", c.spacing, 0, 1e3, true, true);
  c.rest_density = r.number("rest_density", c.rest_density, 0, 1e5, false, true);
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
  c.cfl = r.number("cfl", c.cfl, 0, 1, false, true);
  if (r.has("boundary_layers") && !(r.at("boundary_layers").is_string() && r.at("boundary_layers") == "auto")) {
    const double l = r.number("boundary_layers", 0, 1, 8);
    if (l != std::floor(l)) r.fail("boundary_layers", r.at("boundary_layers"), "must be \"auto\" or an integer 1..8");
    c.boundary_layers = int(l);
  }
  c.presence = r.boolean("presence", c.presence);
  return c;
}

}  // namespace sphray
