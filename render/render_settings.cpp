#include "render_settings.h"

#include <algorithm>

namespace sphray {

RenderSettings read_render_settings(const ConfigReader& r) {
  r.only({"width", "height", "interfaces", "step", "secant_steps", "ior", "absorption", "tint", "reflections",
          "budget", "min_weight", "skip_empty", "eye", "target", "fov", "frames_every"});
  RenderSettings R;
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
