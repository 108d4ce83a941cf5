#include "scene.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "mesh/skin_map.h"
#include "sph/obstacles.h"

namespace sphray {

namespace {

using nlohmann::json;

void apply_override(json& j, const std::string& file, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw SceneError("--set '" + assignment + "': expected key.path=value (e.g. sph.spacing=0.02)");
  const std::string key = assignment.substr(0, eq), text = assignment.substr(eq + 1);
  std::string repeated;
  json value = parse_json_checked(text, repeated, /*allow_exceptions=*/false);
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

Box read_box(const ConfigReader& r, const char* lo_key, const char* hi_key) {
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
  const double g = length(s.gravity) > 0 ? length(s.gravity) : kStandardGravity;
  return std::max(std::sqrt(g * height), vmax);
}

double auto_speed_of_sound(const Scene& s) { return 10.0 * expected_flow_speed(s); }

namespace {

void read_tank(const ConfigReader& tank, Scene& s) {
  tank.only({"min", "max", "open_top", "free_slip"});
  s.tank = read_box(tank, "min", "max");
  s.open_top = tank.boolean("open_top", s.open_top);
  if (!tank.has("free_slip")) return;
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

// run.max_dt's default depends on the solver: WCSPH's steps are bounded by
// the sound speed long before, PBF's and DFSPH's by the flow, which is at
// rest at first.
void read_run(const ConfigReader& run, Scene::Run& r, SolverKind solver) {
  run.only({"end_time", "output_interval", "min_dt", "max_dt"});
  if (incompressible(solver)) r.max_dt = Scene::Run::kFlowMaxDt;
  r.end_time = run.number("end_time", r.end_time, 0, 1e6);
  r.output_interval = run.number("output_interval", r.output_interval, 0, 1e6, false, true);
  r.min_dt = run.number("min_dt", r.min_dt, 0, 1, false, true);
  r.max_dt = run.number("max_dt", r.max_dt, 0, 1, false, true);
  if (r.max_dt < r.min_dt) run.fail("max_dt", json(r.max_dt), "must not be below run.min_dt");
  // Steps land on the output times (no step is cut short just before one),
  // so an interval below the floor would make every step shorter than the
  // floor allows: 1e-9 s would take 1e8 steps to t = 0.1 s.
  if (r.output_interval < r.min_dt) {
    std::ostringstream os;
    os << "is below run.min_dt = " << r.min_dt
       << " s: the steps land on every output time, so each would be shorter than the floor (raise "
          "run.output_interval or lower run.min_dt)";
    run.fail("output_interval", json(r.output_interval), os.str());
  }
}

// The tank against the spacing: wide enough, and near enough the origin.
void check_tank(const ConfigReader& tank, const Scene& s) {
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
}

// Whether the box [lo, hi] lies in the tank, within eps of the tank's size;
// above the rim too where `lid` is false (an open top).
bool within_tank(const Scene& s, Vec3d lo, Vec3d hi, double rel_eps, bool lid) {
  const double eps = rel_eps * std::max(1.0, length(s.tank.max - s.tank.min));
  return lo.x >= s.tank.min.x - eps && lo.y >= s.tank.min.y - eps && lo.z >= s.tank.min.z - eps &&
         hi.x <= s.tank.max.x + eps && hi.y <= s.tank.max.y + eps && (!lid || hi.z <= s.tank.max.z + eps);
}

void read_fluid(const ConfigReader& root, Scene& s) {
  if (!root.has("fluid")) return;
  const json& fl = root.at("fluid");
  if (!fl.is_array()) root.fail("fluid", fl, "must be an array of blocks {\"min\": [..], \"max\": [..]}");
  for (size_t b = 0; b < fl.size(); ++b) {
    const ConfigReader blk(fl[b], root.file(), "fluid." + std::to_string(b));
    blk.only({"min", "max", "velocity"});
    FluidBlock fb{read_box(blk, "min", "max"), blk.vec3("velocity", {0, 0, 0})};
    if (!within_tank(s, fb.box.min, fb.box.max, 1e-9, true)) blk.fail("max", fl[b], "the block lies (partly) outside the tank " + root.at("tank").dump());
    if (length(fb.velocity) > 1e4) blk.fail("velocity", blk.at("velocity"), "speed must be at most 1e4 m/s");
    s.fluid.push_back(fb);
  }
}

// "obstacles.N.motion": a prescribed oscillation, checked to keep the mesh
// inside the tank over a period (its vertices at 256 instants).
void read_motion(const ConfigReader& o, Obstacle& ob, const Scene& s, const ConfigReader& root) {
  const ConfigReader m = o.child("motion");
  m.only({"period", "translate", "rotate", "pivot"});
  const double period = m.number("period", 0, 0, 1e6, true, true);
  const Vec3d tr = m.vec3("translate", {0, 0, 0}), rot = m.vec3("rotate", {0, 0, 0});
  if (std::max({std::abs(rot.x), std::abs(rot.y), std::abs(rot.z)}) > 90)
    m.fail("rotate", m.at("rotate"), "amplitudes must be at most 90 degrees");
  const Box b = bounds(ob.mesh);
  const Vec3d pivot = m.vec3("pivot", (b.min + b.max) * 0.5);
  Motion& mo = ob.motion;
  mo.omega = float(2.0 * M_PI / period);
  mo.translate = {float(tr.x), float(tr.y), float(tr.z)};
  const double k = M_PI / 180.0;
  mo.rotate = {float(rot.x * k), float(rot.y * k), float(rot.z * k)};
  mo.pivot = {float(pivot.x), float(pivot.y), float(pivot.z)};
  for (int j = 0; j < 256; ++j) {
    const double t = period * j / 256.0;
    const RigidFrame f = mo.at(float(t));
    for (const Vec3d& v : ob.mesh.vertices) {
      const Vec3f w = f.to_world({float(v.x), float(v.y), float(v.z)});
      const Vec3d wd{w.x, w.y, w.z};
      if (!within_tank(s, wd, wd, 1e-6, !s.open_top)) {
        std::ostringstream os;
        os << "moves " << ob.path << " out of the tank " << root.at("tank").dump() << " (a vertex reaches (" << w.x
           << ", " << w.y << ", " << w.z << ") at t = " << t << " s)";
        o.fail("motion", o.at("motion"), os.str());
      }
    }
  }
}

// "obstacles.N.skin": waves on the mesh's surface (sph/skin.h). The mesh
// must map one to one onto a sphere (mesh/skin_map.h), checked here.
void read_skin(const ConfigReader& o, Obstacle& ob, const Scene& s) {
  const ConfigReader k = o.child("skin");
  k.only({"resolution", "wave_speed", "damping", "frequency", "compliance", "stencil"});
  if (s.sph.solver == SolverKind::Pbf)
    o.fail("skin", o.at("skin"), "needs a solver with a pressure to drive the waves: sph.solver \"wcsph\" or \"dfsph\" (pbf has none)");
  SkinParams& p = ob.skin;
  p.resolution = k.integer("resolution", p.resolution, 4, 512);
  p.wave_speed = float(k.number("wave_speed", p.wave_speed, 0, 1e3, false, true));
  p.damping = float(k.number("damping", p.damping, 0, 1e4));
  p.frequency = float(k.number("frequency", p.frequency, 0, 1e4, false, true));
  p.compliance = float(k.number("compliance", p.compliance, 0, 1));
  const std::string st = k.string("stencil", "surface", {"surface", "fitted", "texture"});
  p.stencil = st == "surface" ? SkinStencil::Surface : st == "texture" ? SkinStencil::Texture : SkinStencil::Fitted;
  try {
    ob.skin_embedding = embed_on_sphere(ob.mesh);
  } catch (const MeshError& e) {
    o.fail("skin", o.at("skin"), e.what());
  }
  ob.has_skin = true;
}

// "obstacles": meshes read, placed and checked here, so that every problem
// is reported with the key and file before anything runs.
void read_obstacles(const ConfigReader& root, Scene& s) {
  if (!root.has("obstacles")) return;
  const json& list = root.at("obstacles");
  if (!list.is_array())
    root.fail("obstacles", list, "must be an array of obstacles {\"mesh\": \"file.obj\", \"scale\", \"rotate\", \"translate\"}");
  if (list.size() > kMaxObstacles)
    root.fail("obstacles", json(list.size()), "at most " + std::to_string(kMaxObstacles) + " obstacles (merge meshes into one file)");
  const std::filesystem::path folder = std::filesystem::path(root.file()).parent_path();
  for (size_t k = 0; k < list.size(); ++k) {
    const ConfigReader o(list[k], root.file(), "obstacles." + std::to_string(k));
    o.only({"mesh", "scale", "rotate", "translate", "motion", "skin"});
    if (!o.has("mesh") || !o.at("mesh").is_string() || o.at("mesh").get<std::string>().empty())
      o.fail("mesh", o.has("mesh") ? o.at("mesh") : json(), "is required: the path of an OBJ file (relative to the scene file)");
    Obstacle ob;
    const std::filesystem::path given = o.at("mesh").get<std::string>();
    ob.path = given.is_absolute() || folder.empty() ? given.string() : (folder / given).string();
    // The scene as it runs (exports carry it) names the file absolutely, so
    // that `sphray render --from` finds it wherever the export goes.
    s.json["obstacles"][k]["mesh"] = std::filesystem::absolute(ob.path).lexically_normal().string();
    Placement& pl = ob.placement;
    if (o.has("scale") && o.at("scale").is_number()) {
      const double f = o.number("scale", 1.0, 0.0, 1e6, false, true);
      pl.scale = {f, f, f};
    } else {
      pl.scale = o.vec3("scale", pl.scale);
      if (!(pl.scale.x > 0 && pl.scale.y > 0 && pl.scale.z > 0))
        o.fail("scale", o.at("scale"), "every factor must be > 0 (a mesh cannot be mirrored or flattened)");
    }
    pl.rotate_deg = o.vec3("rotate", pl.rotate_deg);
    pl.translate = o.vec3("translate", pl.translate);
    try {
      ob.mesh = placed(read_obj(ob.path), pl);
      const Box b = bounds(ob.mesh);
      const double diag = length(b.max - b.min);
      check_mesh(ob.mesh, 1e-12 * diag * diag);
    } catch (const MeshError& e) {
      throw SceneError(root.file() + ": obstacles." + std::to_string(k) + ".mesh: " + e.what());
    }
    if (signed_volume(ob.mesh) < 0) flip(ob.mesh);  // inward-facing triangles: turned outward
    const Box b = bounds(ob.mesh);
    if (!within_tank(s, b.min, b.max, 1e-9, !s.open_top)) {
      std::ostringstream os;
      os << ob.path << " crosses the tank walls: placed, it spans [" << b.min.x << ", " << b.max.x << "] x [" << b.min.y
         << ", " << b.max.y << "] x [" << b.min.z << ", " << b.max.z << "], the tank " << root.at("tank").dump()
         << " (check scale, rotate and translate)";
      o.fail("mesh", o.at("mesh"), os.str());
    }
    if (o.has("motion")) read_motion(o, ob, s, root);
    if (o.has("skin")) read_skin(o, ob, s);
    s.obstacles.push_back(std::move(ob));
  }
}

void read_gauges(const ConfigReader& root, Scene& s) {
  if (!root.has("gauges")) return;
  const json& list = root.at("gauges");
  if (!list.is_array()) root.fail("gauges", list, "must be an array of gauges {\"name\": \"H1\", \"at\": [x, y]}");
  for (size_t k = 0; k < list.size(); ++k) {
    const ConfigReader g(list[k], root.file(), "gauges." + std::to_string(k));
    g.only({"name", "at"});
    Gauge gauge;
    gauge.name = g.has("name") && g.at("name").is_string() ? g.at("name").get<std::string>() : "";
    if (gauge.name.empty() || gauge.name.find_first_of(",\"\n") != std::string::npos)
      g.fail("name", g.has("name") ? g.at("name") : json(), "is required: a name for the CSV column, without commas or quotes");
    for (const Gauge& other : s.gauges)
      if (other.name == gauge.name) g.fail("name", g.at("name"), "is the name of an earlier gauge");
    const json& at = g.has("at") ? g.at("at") : json();
    if (!at.is_array() || at.size() != 2 || !at[0].is_number() || !at[1].is_number())
      g.fail("at", at, "is required: [x, y], the gauge's vertical line [m]");
    gauge.x = at[0].get<double>();
    gauge.y = at[1].get<double>();
    if (gauge.x < s.tank.min.x || gauge.x > s.tank.max.x || gauge.y < s.tank.min.y || gauge.y > s.tank.max.y)
      g.fail("at", at, "lies outside the tank " + root.at("tank").dump());
    s.gauges.push_back(gauge);
  }
}

// A weakly compressible fluid is meaningful only well below its speed of
// sound (density varies as Mach^2): a c0 under the flow speed the scene can
// be expected to reach would make the run supersonic, and at c0 -> 0 the
// hydrostatic density-diffusion correction (rho0 g / c0^2) blows up. The run
// also stops if a particle outruns c0 (integrate.h, ChooseStep).
void check_speed_of_sound(const ConfigReader& sph, const Scene& s) {
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
}

// The JSON of a scene with its overrides applied.
json scene_json(const std::string& text, const std::string& file, const std::vector<std::string>& overrides) {
  json j;
  std::string repeated;
  try {
    j = parse_json_checked(text, repeated);
  } catch (const json::parse_error& e) {
    throw SceneError(file + ": not valid JSON: " + e.what());
  }
  if (!repeated.empty())
    throw SceneError(file + ": " + repeated + " is given twice (JSON keeps only the last; give it once)");
  if (!j.is_object()) throw SceneError(file + ": the scene must be a JSON object");
  for (const auto& o : overrides) apply_override(j, file, o);
  return j;
}

}  // namespace

Scene parse_scene(const std::string& text, const std::string& file, const std::vector<std::string>& overrides) {
  Scene s;
  s.file = file;
  s.json = scene_json(text, file, overrides);
  const ConfigReader root(s.json, file, "");
  root.only({"name", "description", "tank", "fluid", "obstacles", "gauges", "gravity", "sph", "pbf", "dfsph", "field", "render", "export",
             "run"});
  s.name = root.has("name") && root.at("name").is_string() ? root.at("name").get<std::string>() : "scene";
  if (root.has("name") && !root.at("name").is_string()) root.fail("name", root.at("name"), "must be a string");
  if (root.has("description") && !root.at("description").is_string())
    root.fail("description", root.at("description"), "must be a string");
  if (!root.has("tank")) root.fail("tank", json(), "is required");
  read_tank(root.child("tank"), s);
  s.gravity = root.vec3("gravity", s.gravity);
  if (length(s.gravity) > 1000.0) root.fail("gravity", root.at("gravity"), "magnitude must be at most 1000 m/s^2");
  // Each stage reads its own section.
  s.sph = read_sph_config(root.child("sph"), root.child("pbf"), root.child("dfsph"));
  for (const SolverKind k : {SolverKind::Pbf, SolverKind::Dfsph}) {
    const std::string name = solver_name(k);
    if (root.has(name) && s.sph.solver != k)
      root.fail(name, root.at(name), "holds options of the " + name + " solver, but sph.solver is \"" +
                                         solver_name(s.sph.solver) + "\" (set sph.solver to \"" + name +
                                         "\" or remove the section)");
  }
  s.field = read_field_config(root.child("field"));
  s.field.every_frame = s.field.every_frame && root.has("field");
  s.render = read_render_settings(root.child("render"));
  const ConfigReader exp = root.child("export");
  exp.only({"gzip", "writer"});
  const double gz = exp.number("gzip", s.export_.gzip, 0, 9);
  if (gz != std::floor(gz)) exp.fail("gzip", exp.at("gzip"), "must be an integer 0 (off) .. 9");
  s.export_.gzip = int(gz);
  s.export_.writer = exp.string("writer", s.export_.writer, {"auto", "rank0", "parallel"});
  read_run(root.child("run"), s.run, s.sph.solver);
  check_tank(root.child("tank"), s);
  read_fluid(root, s);
  read_obstacles(root, s);
  read_gauges(root, s);
  if (s.sph.solver == SolverKind::Wcsph) check_speed_of_sound(root.child("sph"), s);
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
