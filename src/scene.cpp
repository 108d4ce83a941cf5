#include "scene.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

namespace sphray {

namespace {

using nlohmann::json;

// Reads one JSON object of the scene, naming `file` and the dotted key in every error.
class Reader {
 public:
  Reader(const json& j, std::string file, std::string path) : j_(j), file_(std::move(file)), path_(std::move(path)) {
    if (!j_.is_object()) fail("", j_, "must be an object");
  }

  [[noreturn]] void fail(const std::string& key, const json& value, const std::string& why) const {
    std::ostringstream os;
    os << file_ << ": " << (key.empty() ? (path_.empty() ? std::string("scene") : path_) : full(key));
    if (!value.is_null() || !key.empty()) os << " = " << value.dump();
    os << ": " << why;
    throw SceneError(os.str());
  }

  std::string full(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  bool has(const std::string& key) const { return j_.contains(key); }
  const json& at(const std::string& key) const { return j_.at(key); }

  void only(std::initializer_list<const char*> keys) const {
    std::set<std::string> allowed(keys.begin(), keys.end());
    for (auto it = j_.begin(); it != j_.end(); ++it) {
      if (!allowed.count(it.key())) {
        std::string list;
        for (auto& k : allowed) list += (list.empty() ? "" : ", ") + k;
        fail(it.key(), it.value(), "unknown key (allowed here: " + list + ")");
      }
    }
  }

  double number(const std::string& key, double def, double lo, double hi, bool required = false,
                bool lo_open = false) const {
    if (!has(key)) {
      if (required) fail(key, json(), "is required");
      return def;
    }
    const json& v = at(key);
    if (!v.is_number()) fail(key, v, "must be a number");
    const double x = v.get<double>();
    if (!std::isfinite(x)) fail(key, v, "must be finite");
    if (x < lo || (lo_open && x == lo) || x > hi) {
      std::ostringstream os;
      os << "must be in " << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
      fail(key, v, os.str());
    }
    return x;
  }

  bool boolean(const std::string& key, bool def) const {
    if (!has(key)) return def;
    if (!at(key).is_boolean()) fail(key, at(key), "must be true or false");
    return at(key).get<bool>();
  }

  std::string string(const std::string& key, const std::string& def, std::initializer_list<const char*> choices) const {
    if (!has(key)) return def;
    const json& v = at(key);
    std::string list;
    for (auto c : choices) list += std::string(list.empty() ? "" : ", ") + "\"" + c + "\"";
    if (!v.is_string()) fail(key, v, "must be one of " + list);
    const std::string s = v.get<std::string>();
    for (auto c : choices)
      if (s == c) return s;
    fail(key, v, "must be one of " + list);
  }

  Vec3d vec3(const std::string& key, Vec3d def, bool required = false) const {
    if (!has(key)) {
      if (required) fail(key, json(), "is required");
      return def;
    }
    const json& v = at(key);
    if (!v.is_array() || v.size() != 3) fail(key, v, "must be an array of three numbers [x, y, z]");
    double c[3];
    for (int k = 0; k < 3; ++k) {
      if (!v[k].is_number()) fail(key, v, "must be an array of three numbers [x, y, z]");
      c[k] = v[k].get<double>();
      if (!std::isfinite(c[k])) fail(key, v, "must be finite");
    }
    return {c[0], c[1], c[2]};
  }

  Reader child(const std::string& key) const {
    static const json empty = json::object();
    return Reader(has(key) ? at(key) : empty, file_, full(key));
  }

  const std::string& file() const { return file_; }

 private:
  const json& j_;
  std::string file_, path_;
};

// JSON text parsed with every object's keys checked for repeats: JSON allows
// them and nlohmann keeps the last, so a scene with two "sph" sections ran
// with the second one silently. Throws json::parse_error as json::parse
// does; returns the dotted key of the first repeat in `repeated`.
json parse_json(const std::string& text, std::string& repeated, bool allow_exceptions = true) {
  struct Level {
    bool array;
    size_t index = 0;  // arrays: the element being read
    std::string key;   // objects: the key being read
    std::set<std::string> keys;
  };
  std::vector<Level> levels;
  auto dotted = [&] {
    std::string path;
    for (const Level& l : levels) path += (path.empty() ? "" : ".") + (l.array ? std::to_string(l.index) : l.key);
    return path;
  };
  auto element_done = [&] {
    if (!levels.empty() && levels.back().array) ++levels.back().index;
  };
  const json::parser_callback_t check = [&](int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start: levels.push_back(Level{false, 0, {}, {}}); break;
      case json::parse_event_t::array_start: levels.push_back(Level{true, 0, {}, {}}); break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        levels.pop_back();
        element_done();
        break;
      case json::parse_event_t::key:
        levels.back().key = parsed.get<std::string>();
        if (!levels.back().keys.insert(levels.back().key).second && repeated.empty()) repeated = dotted();
        break;
      case json::parse_event_t::value: element_done(); break;
    }
    return true;
  };
  return json::parse(text, check, allow_exceptions);
}

void apply_override(json& j, const std::string& file, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw SceneError("--set '" + assignment + "': expected key.path=value (e.g. sph.spacing=0.02)");
  const std::string key = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  std::string repeated;
  json value = parse_json(text, repeated, /*allow_exceptions=*/false);
  if (value.is_discarded()) value = text;  // a bare word is a string
  else if (!repeated.empty())
    throw SceneError("--set " + key + ": the value names '" + repeated + "' twice (JSON keeps only the last)");
  std::string pointer, walked;
  const json* at = &j;  // the value the path has reached, while it exists
  std::stringstream ss(key);
  for (std::string part; std::getline(ss, part, '.');) {
    if (part.empty()) throw SceneError("--set '" + assignment + "': empty component in key path '" + key + "'");
    // fluid[0].max, as other tools write it, read as an object key "fluid[0]"
    // and was refused as unknown at the scene's top level.
    if (part.find('[') != std::string::npos && part.back() == ']')
      throw SceneError(file + ": --set " + key + ": array elements are indexed with a dot: " +
                       std::regex_replace(key, std::regex(R"(\[(\d+)\])"), ".$1"));
    // An array index may name an element or append one (index = size); past
    // that, JSON pointers pad the array with nulls, and validation would then
    // blame an element the user never named.
    if (at && at->is_array()) {
      const bool digits = part.find_first_not_of("0123456789") == std::string::npos && part.size() < 10;
      const size_t k = digits ? std::stoul(part) : 0;
      if (!digits || k > at->size()) {
        std::ostringstream os;
        os << file << ": --set " << key << ": " << walked << " has " << at->size() << " element(s), indexed from 0; '"
           << part << "' is " << (digits ? "past its end (" + walked + "." + std::to_string(at->size()) + " appends one)"
                                         : "not an index");
        throw SceneError(os.str());
      }
      at = k < at->size() ? &(*at)[k] : nullptr;
    } else if (at && at->is_object()) {
      const auto it = at->find(part);
      at = it != at->end() ? &*it : nullptr;
    } else {
      at = nullptr;
    }
    pointer += "/" + part;
    walked += (walked.empty() ? "" : ".") + part;
  }
  try {
    // A missing section is created (so `--set run.end_time=1` works on a scene
    // without "run"); a misspelt key is then caught by validation as unknown.
    j[json::json_pointer(pointer)] = value;
  } catch (const json::exception& e) {
    throw SceneError(file + ": --set " + key + ": cannot set this path (" + e.what() + ")");
  }
}

Box read_box(const Reader& r, const char* lo_key, const char* hi_key) {
  Box b{r.vec3(lo_key, {}, true), r.vec3(hi_key, {}, true)};
  const double lo[3] = {b.min.x, b.min.y, b.min.z}, hi[3] = {b.max.x, b.max.y, b.max.z};
  for (int k = 0; k < 3; ++k)
    if (!(hi[k] > lo[k])) r.fail(hi_key, r.at(hi_key), std::string("must be greater than ") + lo_key + " in every axis");
  return b;
}

}  // namespace

bool is_hdf5_signature(const std::string& head) {
  static const char kSignature[8] = {'\x89', 'H', 'D', 'F', '\r', '\n', '\x1a', '\n'};
  return head.size() >= 8 && head.compare(0, 8, std::string(kSignature, 8)) == 0;
}

Vec3d up_of(const Scene& s) {
  const double g = length(s.gravity);
  return g > 0 ? s.gravity * (-1.0 / g) : Vec3d{0, 0, 1};
}

double box_top(const Box& b, Vec3d up) {
  double top = -1e300;
  for (int c = 0; c < 8; ++c) {
    const Vec3d p{c & 1 ? b.max.x : b.min.x, c & 2 ? b.max.y : b.min.y, c & 4 ? b.max.z : b.min.z};
    top = std::max(top, dot(p, up));
  }
  return top;
}

double expected_flow_speed(const Scene& s) {
  const Vec3d up = up_of(s);
  const double floor = -box_top(s.tank, up * -1.0);
  double top = -1e300, vmax = 0;
  for (const auto& b : s.fluid) {
    top = std::max(top, box_top(b.box, up));
    vmax = std::max(vmax, length(b.velocity));
  }
  const double dx = s.sph.spacing;
  const double height = s.fluid.empty() ? dx : std::max(top - floor, dx);
  const double g = length(s.gravity) > 0 ? length(s.gravity) : 9.81;
  return std::max(std::sqrt(g * height), vmax);
}

double auto_speed_of_sound(const Scene& s) { return 10.0 * expected_flow_speed(s); }

int auto_boundary_layers(const Scene& s) { return int(std::ceil(2.0 * s.sph.smoothing_ratio - 1e-9)); }

Scene parse_scene(const std::string& text, const std::string& file, const std::vector<std::string>& overrides) {
  json j;
  std::string repeated;
  try {
    j = parse_json(text, repeated);
  } catch (const json::parse_error& e) {
    throw SceneError(file + ": not valid JSON: " + e.what());
  }
  if (!repeated.empty())
    throw SceneError(file + ": " + repeated + " is given twice (JSON keeps only the last; give it once)");
  if (!j.is_object()) throw SceneError(file + ": the scene must be a JSON object");
  for (const auto& o : overrides) apply_override(j, file, o);

  Scene s;
  s.file = file;
  s.json = j;
  const Reader root(j, file, "");
  root.only({"name", "description", "tank", "fluid", "gravity", "sph", "field", "render", "export", "run"});
  s.name = root.has("name") && root.at("name").is_string() ? root.at("name").get<std::string>() : "scene";
  if (root.has("name") && !root.at("name").is_string()) root.fail("name", root.at("name"), "must be a string");
  if (root.has("description") && !root.at("description").is_string())
    root.fail("description", root.at("description"), "must be a string");

  if (!root.has("tank")) root.fail("tank", json(), "is required");
  const Reader tank = root.child("tank");
  tank.only({"min", "max", "open_top", "free_slip"});
  s.tank = read_box(tank, "min", "max");
  s.open_top = tank.boolean("open_top", false);
  if (tank.has("free_slip")) {
    static const char* faces[6] = {"-x", "+x", "-y", "+y", "-z", "+z"};
    const json& fs = tank.at("free_slip");
    if (!fs.is_array()) tank.fail("free_slip", fs, "must be an array of faces from \"-x\", \"+x\", \"-y\", \"+y\", \"-z\", \"+z\"");
    for (const auto& f : fs) {
      int k = 0;
      while (k < 6 && !(f.is_string() && f == faces[k])) ++k;
      if (k == 6) tank.fail("free_slip", fs, "unknown face " + f.dump() + " (faces: \"-x\", \"+x\", \"-y\", \"+y\", \"-z\", \"+z\")");
      s.free_slip[k] = true;
    }
  }

  s.gravity = root.vec3("gravity", s.gravity);
  const double gmag = length(s.gravity);
  if (gmag > 1000.0) root.fail("gravity", root.at("gravity"), "magnitude must be at most 1000 m/s^2");

  const Reader sph = root.child("sph");
  sph.only({"spacing", "rest_density", "speed_of_sound", "smoothing_ratio", "kernel", "viscosity_alpha",
            "wall_viscosity_alpha", "density_diffusion", "cfl", "boundary_layers", "presence"});
  s.sph.spacing = sph.number("spacing", 0, 0, 1e3, true, true);
  s.sph.rest_density = sph.number("rest_density", 1000, 0, 1e5, false, true);
  if (sph.has("speed_of_sound") && sph.at("speed_of_sound").is_string()) {
    if (sph.at("speed_of_sound") != "auto")
      sph.fail("speed_of_sound", sph.at("speed_of_sound"), "must be \"auto\" or a positive number [m/s]");
  } else {
    s.sph.speed_of_sound = sph.has("speed_of_sound") ? sph.number("speed_of_sound", 0, 0, 1e5, false, true) : 0.0;
  }
  s.sph.smoothing_ratio = sph.number("smoothing_ratio", 2.0, 1.0, 3.0);
  s.sph.kernel = sph.string("kernel", "wendland_c2", {"wendland_c2", "cubic_spline"}) == "cubic_spline"
                     ? KernelType::CubicSpline
                     : KernelType::WendlandC2;
  s.sph.viscosity_alpha = sph.number("viscosity_alpha", 0.02, 0, 1);
  s.sph.wall_viscosity_alpha = sph.number("wall_viscosity_alpha", -1, 0, 1);
  s.sph.density_diffusion = sph.number("density_diffusion", 0.1, 0, 1);
  s.sph.cfl = sph.number("cfl", 0.25, 0, 1, false, true);
  if (sph.has("boundary_layers") && !(sph.at("boundary_layers").is_string() && sph.at("boundary_layers") == "auto")) {
    const double l = sph.number("boundary_layers", 0, 1, 8);
    if (l != std::floor(l)) sph.fail("boundary_layers", sph.at("boundary_layers"), "must be \"auto\" or an integer 1..8");
    s.sph.boundary_layers = int(l);
  }
  s.sph.presence = sph.boolean("presence", false);

  const Reader field = root.child("field");
  field.only({"builder", "refine", "radius", "core", "clip", "min_extent", "shrink_from", "full_fraction", "full_value"});
  s.field.given = root.has("field");
  s.field.builder = field.string("builder", "presence", {"naive", "presence", "gather"});
  const double refine = field.number("refine", 2, 0, 2);
  if (refine != std::floor(refine)) field.fail("refine", field.at("refine"), "must be 0, 1 or 2 (voxels per cell edge = 2^refine)");
  s.field.refine = int(refine);
  s.field.radius = field.number("radius", 2.0, 1.0, 8.0);
  s.field.core = field.number("core", 0.5, 0.05, 4.0);
  s.field.clip = field.number("clip", 4.0, 1.01, 1e3);
  s.field.min_extent = field.number("min_extent", 1.0, 0.0, 8.0);
  if (s.field.min_extent > s.field.radius)
    field.fail("min_extent", field.at("min_extent"), "must not exceed field.radius");
  s.field.shrink_from = field.number("shrink_from", 0.5, 0.0, 0.95);
  s.field.full_fraction = field.number("full_fraction", 0.9, 0.1, 2.0);
  s.field.full_value = field.string("full_value", "clip", {"clip", "coarse"});

  const Reader rd = root.child("render");
  rd.only({"width", "height", "interfaces", "step", "secant_steps", "ior", "absorption", "skip_empty", "eye", "target",
           "fov", "frames_every"});
  auto integer = [](const Reader& r, const char* key, double def, double lo, double hi) {
    const double v = r.number(key, def, lo, hi);
    if (v != std::floor(v)) r.fail(key, r.at(key), "must be an integer");
    return int(v);
  };
  RenderSettings& R = s.render;
  R.width = integer(rd, "width", R.width, 16, 8192);
  R.height = integer(rd, "height", R.height, 16, 8192);
  R.interfaces = integer(rd, "interfaces", R.interfaces, 1, 8);
  R.step = float(rd.number("step", R.step, 0.0, 0.5, false, true));
  R.secant_steps = integer(rd, "secant_steps", R.secant_steps, 0, 16);
  R.ior = float(rd.number("ior", R.ior, 1.0, 3.0));
  R.absorption = rd.vec3("absorption", R.absorption);
  if (std::min({R.absorption.x, R.absorption.y, R.absorption.z}) < 0 ||
      std::max({R.absorption.x, R.absorption.y, R.absorption.z}) > 1e4)
    rd.fail("absorption", rd.at("absorption"), "must be three coefficients in [0, 1e4] per metre");
  R.skip_empty = rd.boolean("skip_empty", R.skip_empty);
  R.eye = rd.vec3("eye", R.eye);
  R.target = rd.vec3("target", R.target);
  if (rd.has("eye") != rd.has("target")) rd.fail(rd.has("eye") ? "target" : "eye", json(), "is required with the other camera point");
  if (rd.has("eye") && !(length(R.eye - R.target) > 0)) rd.fail("target", rd.at("target"), "must differ from render.eye");
  R.fov = rd.number("fov", R.fov, 1.0, 170.0);
  R.frames_every = integer(rd, "frames_every", R.frames_every, 1, 1000000);

  const Reader exp = root.child("export");
  exp.only({"gzip"});
  const double gz = exp.number("gzip", 0, 0, 9);
  if (gz != std::floor(gz)) exp.fail("gzip", exp.at("gzip"), "must be an integer 0 (off) .. 9");
  s.export_.gzip = int(gz);

  const Reader run = root.child("run");
  run.only({"end_time", "output_interval", "min_dt", "max_dt"});
  s.run.end_time = run.number("end_time", 1.0, 0, 1e6);
  s.run.output_interval = run.number("output_interval", 0.01, 0, 1e6, false, true);
  s.run.min_dt = run.number("min_dt", 1e-8, 0, 1, false, true);
  s.run.max_dt = run.number("max_dt", 1e-3, 0, 1, false, true);
  if (s.run.max_dt < s.run.min_dt) run.fail("max_dt", json(s.run.max_dt), "must not be below run.min_dt");

  const double dx = s.sph.spacing;
  const Vec3d tank_size = s.tank.max - s.tank.min;
  if (std::min({tank_size.x, tank_size.y, tank_size.z}) < 2 * dx)
    tank.fail("max", tank.at("max"), "the tank must be at least two particle spacings (sph.spacing) wide in every axis");
  // Positions are single precision on both backends: 2^-24 of a coordinate.
  // Within 16384 spacings of the origin that is under 1/1000 of a spacing; a
  // tank placed far out (map coordinates) would run with distances, and so
  // pressures, rounded to a visible fraction of a particle.
  constexpr double kMaxSpacingsFromOrigin = 16384;
  for (const auto& [corner, c] : {std::pair{"min", s.tank.min}, std::pair{"max", s.tank.max}}) {
    const double far = std::max({std::abs(c.x), std::abs(c.y), std::abs(c.z)});
    if (far > kMaxSpacingsFromOrigin * dx) {
      std::ostringstream os;
      os << "lies " << far / dx << " particle spacings from the origin: positions are single precision, which resolve "
         << "1/1000 of a spacing only within " << kMaxSpacingsFromOrigin << " spacings (" << kMaxSpacingsFromOrigin * dx
         << " m here); move the tank nearer the origin";
      tank.fail(corner, tank.at(corner), os.str());
    }
  }

  if (root.has("fluid")) {
    const json& fl = root.at("fluid");
    if (!fl.is_array()) root.fail("fluid", fl, "must be an array of blocks {\"min\": [..], \"max\": [..]}");
    for (size_t b = 0; b < fl.size(); ++b) {
      const Reader blk(fl[b], file, "fluid." + std::to_string(b));
      blk.only({"min", "max", "velocity"});
      FluidBlock fb{read_box(blk, "min", "max"), blk.vec3("velocity", {0, 0, 0})};
      const double eps = 1e-9 * std::max(1.0, length(tank_size));
      const bool inside = fb.box.min.x >= s.tank.min.x - eps && fb.box.min.y >= s.tank.min.y - eps &&
                          fb.box.min.z >= s.tank.min.z - eps && fb.box.max.x <= s.tank.max.x + eps &&
                          fb.box.max.y <= s.tank.max.y + eps && fb.box.max.z <= s.tank.max.z + eps;
      if (!inside) blk.fail("max", fl[b], "the block lies (partly) outside the tank " + root.at("tank").dump());
      if (length(fb.velocity) > 1e4) blk.fail("velocity", blk.at("velocity"), "speed must be at most 1e4 m/s");
      s.fluid.push_back(fb);
    }
  }

  // A weakly compressible fluid is meaningful only well below its speed of
  // sound (density varies as Mach^2): a c0 under the flow speed the scene can
  // be expected to reach would make the run supersonic, and at c0 -> 0 the
  // hydrostatic density-diffusion correction (rho0 g / c0^2) blows up. The run
  // also stops if a particle outruns c0 (integrate.h, ChooseStep).
  const double v_expected = expected_flow_speed(s);
  if (s.sph.speed_of_sound > 0 && s.sph.speed_of_sound < v_expected) {
    std::ostringstream os;
    os.precision(3);
    os << "is below the flow speed this scene can reach, " << v_expected
       << " m/s (sqrt(g H), H the height of its liquid's top above the tank floor, or its fastest initial "
       << "velocity): the flow would be supersonic. "
       << "Weakly compressible SPH wants about 10x that (\"auto\": " << auto_speed_of_sound(s) << " m/s)";
    sph.fail("speed_of_sound", sph.at("speed_of_sound"), os.str());
  }
  return s;
}

std::string read_scene_text(const std::string& path) {
  // A directory opens as an empty stream on Linux, which read as "not valid JSON".
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw SceneError(path + ": is a directory, not a scene file");
  std::ifstream f(path, std::ios::binary);
  if (!f) throw SceneError("cannot open scene file '" + path + "'");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  if (is_hdf5_signature(text))
    throw SceneError(path + ": is an HDF5 file, not a scene (JSON): render it with `sphray render --from " + path +
                     "`, or list its frames with `sphray inspect " + path + "`");
  return text;
}

Scene load_scene(const std::string& path, const std::vector<std::string>& overrides) {
  return parse_scene(read_scene_text(path), path, overrides);
}

}  // namespace sphray
