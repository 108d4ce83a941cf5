#include "skin.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <numeric>
#include <ostream>

#include "bench/sim.h"
#include "mesh/mesh.h"
#include "sph/skin.h"

namespace sphray {

namespace {

constexpr int kDirections = 16;

// Along each great circle leaving `src`, the geodesic distance in [lo, hi]
// where the height, read through the cube map, peaks (a parabola through the
// samples around the largest).
std::array<double, kDirections> ring_radius(const SkinMap& map, const std::vector<float>& h, Vec3d src, double lo,
                                            double hi) {
  const Vec3d e1 = normalized(cross(src, std::abs(src.z) < 0.9 ? Vec3d{0, 0, 1} : Vec3d{1, 0, 0})), e2 = cross(src, e1);
  std::array<double, kDirections> out{};
  const int samples = 400;
  const double step = (hi - lo) / samples;
  std::vector<double> v(samples + 1);
  for (int k = 0; k < kDirections; ++k) {
    const double phi = 2 * M_PI * k / kDirections;
    const Vec3d dir = e1 * std::cos(phi) + e2 * std::sin(phi);
    for (int s = 0; s <= samples; ++s) {
      const double rho = lo + s * step;
      v[s] = map.sample(h, src * std::cos(rho) + dir * std::sin(rho));
    }
    const int best = int(std::max_element(v.begin() + 1, v.end() - 1) - v.begin());
    const double denom = v[best - 1] - 2 * v[best] + v[best + 1];
    const double shift = denom < 0 ? 0.5 * (v[best - 1] - v[best + 1]) / denom : 0.0;
    out[k] = lo + (best + shift) * step;
  }
  return out;
}

}  // namespace

const char* stencil_name(SkinStencil s) {
  switch (s) {
    case SkinStencil::Texture: return "texture";
    case SkinStencil::Fitted: return "fitted";
    default: return "surface";
  }
}

SkinImpulseSpeeds skin_impulse_speeds(Backend b, int resolution, SkinStencil stencil, Vec3d source, int warmup,
                                      int frames) {
  SkinInput in;
  in.mesh = sphere_mesh({0, 0, 0}, 1.0, 5, "unit sphere");
  in.params.resolution = resolution;
  in.params.wave_speed = 1.0f;
  in.params.damping = 0.0f;
  in.params.frequency = 1e-6f;
  in.params.compliance = 0.0f;
  in.params.stencil = stencil;
  std::vector<SkinGeometry> geo;
  geo.push_back(make_skin_geometry(in));
  const Vec3d src = normalized(source);
  SkinImpulseSpeeds out;
  out.texels = geo[0].map.size();
  out.spacing = geo[0].map.mean_spacing;
  const double sigma = 3.0 * out.spacing;
  std::vector<float> h0(out.texels);
  for (size_t i = 0; i < out.texels; ++i) {
    const double rho = std::acos(std::clamp(dot(normalized(geo[0].map.point[i]), src), -1.0, 1.0));
    h0[i] = float(std::exp(-rho * rho / (2 * sigma * sigma)));
  }
  const double dt = 0.5 * geo[0].max_substep;  // one substep per advance
  auto skins = b == Backend::Cuda ? make_cuda_skin_set(std::move(geo), SphParams{}) : make_cpu_skin_set(std::move(geo), SphParams{});
  std::vector<double> ms;
  for (int k = 0; k < warmup + frames; ++k) {
    skins->advance(ParticleView{}, nullptr, 0.0, dt);
    if (k >= warmup) ms.push_back(skins->last_ms());
  }
  out.substep_ms = median(ms);
  skins->set_heights(0, h0);
  const double t1 = 0.6, t2 = 1.4;
  const int n1 = int(std::lround(t1 / dt)), n2 = int(std::lround(t2 / dt));
  std::array<double, kDirections> r1{}, r2{};
  for (int k = 0; k < n2; ++k) {
    skins->advance(ParticleView{}, nullptr, k * dt, dt);
    if (k + 1 == n1) r1 = ring_radius(skins->geometry(0).map, skins->heights(0), src, n1 * dt - 0.35, n1 * dt + 0.35);
  }
  r2 = ring_radius(skins->geometry(0).map, skins->heights(0), src, n2 * dt - 0.35, n2 * dt + 0.35);
  std::array<double, kDirections> v{};
  for (int k = 0; k < kDirections; ++k) v[k] = (r2[k] - r1[k]) / ((n2 - n1) * dt);
  out.mean = std::accumulate(v.begin(), v.end(), 0.0) / kDirections;
  out.min = *std::min_element(v.begin(), v.end());
  out.max = *std::max_element(v.begin(), v.end());
  return out;
}

std::vector<BenchSkinRow> bench_skin(Backend b, const BenchSkinOptions& opt, std::ostream& log) {
  std::vector<BenchSkinRow> rows;
  for (const int n : opt.resolutions)
    for (const SkinStencil s : {SkinStencil::Texture, SkinStencil::Surface, SkinStencil::Fitted}) {
      log << "  " << n << " texels per cube edge, " << stencil_name(s) << " stencil\n";
      rows.push_back({n, stencil_name(s), skin_impulse_speeds(b, n, s, {0.3, 0.5, 0.8}, opt.warmup, opt.frames)});
    }
  return rows;
}

nlohmann::json to_json(const std::vector<BenchSkinRow>& rows, Backend b, const BenchSkinOptions& opt) {
  nlohmann::json j = bench_json("skin", b, "speeds in units of the set speed; median ms", {});
  j["warmup"] = opt.warmup;
  j["measured"] = opt.frames;
  for (const auto& r : rows)
    j["rows"].push_back({{"resolution", r.resolution}, {"stencil", r.stencil}, {"texels", r.speeds.texels},
                         {"spacing", r.speeds.spacing}, {"speed_mean", r.speeds.mean}, {"speed_min", r.speeds.min},
                         {"speed_max", r.speeds.max}, {"substep_ms", r.speeds.substep_ms}});
  return j;
}

void print_table(const std::vector<BenchSkinRow>& rows, std::ostream& out) {
  out << std::setw(6) << "n" << std::setw(9) << "stencil" << std::setw(8) << "texels" << std::setw(10) << "speed"
      << std::setw(9) << "slowest" << std::setw(9) << "fastest" << std::setw(8) << "spread" << std::setw(12)
      << "substep ms\n";
  out << std::fixed;
  for (const auto& r : rows)
    out << std::setw(6) << r.resolution << std::setw(9) << r.stencil << std::setw(8) << r.speeds.texels
        << std::setprecision(3) << std::setw(10) << r.speeds.mean << std::setw(9) << r.speeds.min << std::setw(9)
        << r.speeds.max << std::setprecision(1) << std::setw(7) << 100 * (r.speeds.max - r.speeds.min) / r.speeds.mean
        << "%" << std::setprecision(4) << std::setw(11) << r.speeds.substep_ms << "\n";
}

}  // namespace sphray
