// `sphray bench skin`: waves on an obstacle's skin (sph/skin.h) against the
// analytic wave speed. A Gaussian bump (three texel spacings wide) on the
// unit sphere, free waves at speed 1 (no damping, no foundation, no load);
// along 16 great circles from the bump the ring's peak is found at t = 0.6 s
// and 1.4 s through the cube map, and its speed in each direction is the
// distance travelled over the time. Per cube-map resolution and stencil:
// the mean, slowest and fastest direction, and the device time of one
// substep of every texel (after warm-up, median).
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/device.h"
#include "core/vec.h"
#include "sph/skin_params.h"

namespace sphray {

struct SkinImpulseSpeeds {
  double mean = 0, min = 0, max = 0;  // [m/s], the set speed being 1
  size_t texels = 0;
  double spacing = 0;     // mean texel spacing on the sphere [m]
  double substep_ms = 0;  // one substep of all texels, median after warm-up
};
// The impulse from direction `source` on the sphere.
SkinImpulseSpeeds skin_impulse_speeds(Backend b, int resolution, SkinStencil stencil, Vec3d source, int warmup = 2,
                                      int frames = 10);
const char* stencil_name(SkinStencil s);

struct BenchSkinOptions {
  std::vector<int> resolutions{24, 48, 96};
  int warmup = 2, frames = 10;
};
struct BenchSkinRow {
  int resolution = 0;
  std::string stencil;
  SkinImpulseSpeeds speeds;
};
std::vector<BenchSkinRow> bench_skin(Backend b, const BenchSkinOptions& opt, std::ostream& log);
nlohmann::json to_json(const std::vector<BenchSkinRow>& rows, Backend b, const BenchSkinOptions& opt);
void print_table(const std::vector<BenchSkinRow>& rows, std::ostream& out);

}  // namespace sphray
