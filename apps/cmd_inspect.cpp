// `sphray inspect FILE`: a summary of an HDF5 export: frames, times,
// particle counts and value ranges.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>

#include "commands.h"
#include <nlohmann/json.hpp>

#include "io/frames_h5.h"

namespace sphray::cli {

namespace {

int cmd_inspect(const std::string& path) {
  const FrameReader r(path);
  std::string name = "?";
  try {
    name = nlohmann::json::parse(r.header().scene_json).value("name", "?");
  } catch (...) {
  }
  std::cout << path << ": sphray frames, format_version " << r.format_version() << ", written by sphray "
            << r.header().version << " (" << r.header().backend << " backend), scene \"" << name << "\"\n"
            << "  boundary particles " << r.header().boundary.size() / 3 << ", frames " << r.frames().size() << "\n";
  // [lo, hi] of the finite values; non-finite ones counted after it.
  auto range = [](const std::vector<float>& v, size_t stride, size_t c) {
    float lo = 0, hi = 0;
    size_t finite = 0, other = 0;
    for (size_t k = c; k < v.size(); k += stride) {
      if (!std::isfinite(v[k])) {
        ++other;
        continue;
      }
      lo = finite == 0 ? v[k] : std::min(lo, v[k]);
      hi = finite == 0 ? v[k] : std::max(hi, v[k]);
      ++finite;
    }
    std::ostringstream os;
    if (finite) os << "[" << lo << ", " << hi << "]";
    else os << "(no finite value)";
    if (other) os << " (" << other << " non-finite)";
    return os.str();
  };
  for (size_t k = 0; k < r.frames().size(); ++k) {
    const FrameInfo& fi = r.frames()[k];
    const Frame f = r.read(k);
    std::cout << "  " << fi.name << "  t = " << fi.time << " s  step " << fi.step << "  " << fi.particles
              << " particles";
    if (fi.particles)  // none left (an open top): no ranges to print
      std::cout << "  x " << range(f.position, 3, 0) << " y " << range(f.position, 3, 1) << " z "
                << range(f.position, 3, 2);
    if (!f.density.empty()) std::cout << "  density " << range(f.density, 1, 0);
    if (!f.pressure.empty()) std::cout << "  pressure " << range(f.pressure, 1, 0);
    if (!f.velocity.empty()) {
      float vmax = 0;
      size_t other = 0;
      for (size_t i = 0; i + 2 < f.velocity.size(); i += 3) {
        const float v = std::sqrt(f.velocity[i] * f.velocity[i] + f.velocity[i + 1] * f.velocity[i + 1] +
                                  f.velocity[i + 2] * f.velocity[i + 2]);
        if (std::isfinite(v)) vmax = std::max(vmax, v);
        else ++other;
      }
      std::cout << "  |v| max " << vmax;
      if (other) std::cout << " (" << other << " non-finite)";
    }
    if (!f.presence.empty()) std::cout << "  presence " << range(f.presence, 1, 0);
    if (!f.field.empty())
      std::cout << "  field " << f.field_dims[0] << "x" << f.field_dims[1] << "x" << f.field_dims[2] << " "
                << range(f.field, 1, 0) << " iso " << f.field_iso;
    std::cout << "\n";
  }
  return 0;
}

}  // namespace

CLI::App* add_inspect_command(CLI::App& app, int& exit_code) {
  auto path = std::make_shared<std::string>();
  auto* inspect = app.add_subcommand("inspect", "summary of an HDF5 frames file: frames, times, counts, value ranges");
  inspect->add_option("file", *path, "a file written by sphray run --export")->required();
  inspect->callback([path, &exit_code] { exit_code = cmd_inspect(*path); });
  return inspect;
}

}  // namespace sphray::cli
