#include "surface_error.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "render/raycast.h"

namespace sphray {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct Marcher {
  TrilinearField f;
  float iso;
  const VolumeGeom& vol;

  Vec3f voxels(Vec3d p) const { return vol.to_voxels(Vec3f{float(p.x), float(p.y), float(p.z)}); }

  // The first point of o + t d (voxel units, d unit, t in [0, t_max]) where
  // the field reaches iso: samples every 1/20 voxel, then bisection to 1e-4
  // voxel. -1 when none.
  double first_inside(Vec3f o, Vec3f d, double t_max) const {
    const double step = 0.05;
    double prev = 0.0;
    if (f(o) >= iso) return 0.0;
    for (double t = step; t <= t_max + 1e-9; t += step) {
      if (f(o + d * float(t)) >= iso) {
        double a = prev, b = t;
        while (b - a > 1e-4) {
          const double m = 0.5 * (a + b);
          if (f(o + d * float(m)) >= iso) b = m; else a = m;
        }
        return 0.5 * (a + b);
      }
      prev = t;
    }
    return -1.0;
  }
};

struct Accumulator {
  SurfaceError e;
  double sum2 = 0, sum = 0, ang2 = 0;
  void add(double dist, double angle_deg) {
    ++e.rays;
    sum += dist;
    sum2 += dist * dist;
    ang2 += angle_deg * angle_deg;
    e.max_distance = std::max(e.max_distance, std::abs(dist));
    e.max_angle_deg = std::max(e.max_angle_deg, angle_deg);
  }
  SurfaceError done() {
    const size_t hit = e.rays;
    e.rays += e.missed;
    if (hit > 0) {
      e.mean_distance = sum / double(hit);
      e.rms_distance = std::sqrt(sum2 / double(hit));
      e.rms_angle_deg = std::sqrt(ang2 / double(hit));
    }
    return e;
  }
};

double angle_deg(Vec3f n, Vec3f want) {
  const double c = std::clamp(double(dot(n, want)), -1.0, 1.0);
  return std::acos(c) * 180.0 / kPi;
}

void check(const std::vector<float>& field, const VolumeGeom& vol) {
  if (field.size() != vol.num_voxels()) throw std::invalid_argument("surface error: field and volume sizes differ");
}

// Calls f(x, y) at the centres of a grid of pitch over [lo, hi] in x and y.
template <class F>
void for_each_column(Vec3d lo, Vec3d hi, double pitch, F&& f) {
  if (!(pitch > 0.0)) throw std::invalid_argument("surface error: the ray pitch must be positive");
  const int nx = std::max(1, int(std::floor((hi.x - lo.x) / pitch))), ny = std::max(1, int(std::floor((hi.y - lo.y) / pitch)));
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) f(lo.x + (i + 0.5) * (hi.x - lo.x) / nx, lo.y + (j + 0.5) * (hi.y - lo.y) / ny);
}

}  // namespace

SurfaceError plane_surface_error(const std::vector<float>& field, const VolumeGeom& vol, float iso, Vec3d lo,
                                 Vec3d hi, double height, double pitch) {
  check(field, vol);
  const Marcher m{TrilinearField{field.data(), vol.nx, vol.ny, vol.nz}, iso, vol};
  const Vec3f down{0, 0, -1}, up{0, 0, 1};
  const double t_max = (hi.z - lo.z) / vol.voxel;
  Accumulator acc;
  for_each_column(lo, hi, pitch, [&](double x, double y) {
    const Vec3f o = m.voxels({x, y, hi.z});
    const double t = m.first_inside(o, down, t_max);
    if (t < 0.0) { ++acc.e.missed; return; }
    const double z = hi.z - t * vol.voxel;
    acc.add(z - height, angle_deg(field_normal(m.f, o + down * float(t)), up));
  });
  return acc.done();
}

SurfaceError sphere_surface_error(const std::vector<float>& field, const VolumeGeom& vol, float iso, Vec3d centre,
                                  double radius, int rays, double margin) {
  check(field, vol);
  if (rays < 1 || !(radius > 0.0) || !(margin > 0.0)) throw std::invalid_argument("surface error: bad sphere");
  const Marcher m{TrilinearField{field.data(), vol.nx, vol.ny, vol.nz}, iso, vol};
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  Accumulator acc;
  for (int k = 0; k < rays; ++k) {
    const double z = 1.0 - (2.0 * k + 1.0) / rays, r = std::sqrt(std::max(0.0, 1.0 - z * z)), phi = golden * k;
    const Vec3d out{r * std::cos(phi), r * std::sin(phi), z};
    const Vec3d start{centre.x + out.x * (radius + margin), centre.y + out.y * (radius + margin),
                      centre.z + out.z * (radius + margin)};
    const Vec3f o = m.voxels(start), d{-float(out.x), -float(out.y), -float(out.z)};
    const double t = m.first_inside(o, d, (radius + margin) / vol.voxel);
    if (t < 0.0) { ++acc.e.missed; continue; }
    const double dist = margin - t * vol.voxel;  // from the analytic surface, outward positive
    acc.add(dist, angle_deg(field_normal(m.f, o + d * float(t)), -d));
  }
  return acc.done();
}

SheetHoles sheet_holes(const std::vector<float>& field, const VolumeGeom& vol, float iso, Vec3d lo, Vec3d hi,
                       double pitch) {
  check(field, vol);
  const Marcher m{TrilinearField{field.data(), vol.nx, vol.ny, vol.nz}, iso, vol};
  const double t_max = (hi.z - lo.z) / vol.voxel;
  SheetHoles h;
  for_each_column(lo, hi, pitch, [&](double x, double y) {
    ++h.rays;
    if (m.first_inside(m.voxels({x, y, hi.z}), Vec3f{0, 0, -1}, t_max) < 0.0) ++h.holes;
  });
  return h;
}

}  // namespace sphray
