#include "render_settings.h"

#include <algorithm>
#include <stdexcept>

namespace sphray {

const char* render_method_name(RenderMethod m) {
  switch (m) {
    case RenderMethod::ScreenSpace: return "screen_space";
    case RenderMethod::Slices: return "slices";
    default: return "raycast";
  }
}

RenderMethod parse_render_method(const std::string& name) {
  for (RenderMethod m : {RenderMethod::Raycast, RenderMethod::ScreenSpace, RenderMethod::Slices})
    if (name == render_method_name(m)) return m;
  throw std::invalid_argument("unknown render method '" + name + "' (raycast, screen_space or slices)");
}

RenderSettings read_render_settings(const ConfigReader& r) {
  r.only({"method", "width", "height", "interfaces", "step", "secant_steps", "ior", "absorption", "tint", "reflections",
          "budget", "min_weight", "skip_empty", "eye", "target", "fov", "frames_every", "sphere_radius", "filter_width", "filter_iterations", "slices"});
  RenderSettings R;
  R.method = parse_render_method(r.string("method", "raycast", {"raycast", "screen_space", "slices"}));
  R.width = r.integer("width", R.width, 16, 8192);
  R.height = r.integer("height", R.height, 16, 8192);
  R.interfaces = r.integer("interfaces", R.interfaces, 1, 8);
  R.step = float(r.number("step", R.step, 0.0, 0.5, false, true));
  R.secant_steps = r.integer("secant_steps", R.secant_steps, 0, 16);
  R.ior = float(r.number("ior", R.ior, 1.0, 3.0));
  // r, g, b, each in [0, hi]
  auto rgb = [&](const char* key, Vec3d def, double hi, const char* must) {
    const Vec3d v = r.vec3(key, def);
    if (std::min({v.x, v.y, v.z}) < 0 || std::max({v.x, v.y, v.z}) > hi) r.fail(key, r.at(key), must);
    return v;
  };
  R.absorption = rgb("absorption", R.absorption, 1e4, "must be three coefficients in [0, 1e4] per metre");
  R.tint = rgb("tint", R.tint, 1.0, "must be three linear colour values in [0, 1]");
  R.reflections = r.boolean("reflections", R.reflections);
  R.budget = r.integer("budget", R.budget, 1, 64);
  R.min_weight = r.number("min_weight", R.min_weight, 0.0, 1.0);
  R.skip_empty = r.boolean("skip_empty", R.skip_empty);
  R.sphere_radius = r.number("sphere_radius", R.sphere_radius, 0.0, 4.0, false, true);
  R.filter_width = r.integer("filter_width", R.filter_width, 1, 16);
  R.filter_iterations = r.integer("filter_iterations", R.filter_iterations, 0, 64);
  R.slices = r.integer("slices", R.slices, 8, 4096);
  R.eye = r.vec3("eye", R.eye);
  R.target = r.vec3("target", R.target);
  if (r.has("eye") != r.has("target"))
    r.fail(r.has("eye") ? "target" : "eye", nlohmann::json(), "is required with the other camera point");
  if (r.has("eye") && !(length(R.eye - R.target) > 0)) r.fail("target", r.at("target"), "must differ from render.eye");
  R.fov = r.number("fov", R.fov, 1.0, 170.0);
  R.frames_every = r.integer("frames_every", R.frames_every, 1, 1000000);
  return R;
}

}  // namespace sphray
