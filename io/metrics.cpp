#include "metrics.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace sphray {

double surge_front(const FlowSums& f, double back_wall_x, double spacing) {
  return std::max(back_wall_x, f.max_x + 0.5 * spacing) - back_wall_x;
}

double surge_front(const HostParticles& p, double back_wall_x, double spacing) {
  return surge_front(flow_sums_of(p), back_wall_x, spacing);
}

double kinetic_energy(const FlowSums& f, double particle_mass) { return 0.5 * particle_mass * f.speed2_sum; }

double kinetic_energy(const HostParticles& p, double particle_mass) {
  return kinetic_energy(flow_sums_of(p), particle_mass);
}

Curve read_csv_curve(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("cannot open '" + path + "'");
  Curve c;
  bool header = false;
  for (std::string line; std::getline(f, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    double a, b;
    if (!(ss >> a >> b)) {
      if (!header && c.x.empty()) { header = true; continue; }
      throw std::runtime_error(path + ": cannot read two numbers from line '" + line + "'");
    }
    c.x.push_back(a);
    c.y.push_back(b);
  }
  if (c.x.empty()) throw std::runtime_error(path + ": no data");
  return c;
}

double interpolate(const Curve& c, double x) {
  if (x <= c.x.front()) return c.y.front();
  if (x >= c.x.back()) return c.y.back();
  const size_t k = size_t(std::upper_bound(c.x.begin(), c.x.end(), x) - c.x.begin());
  const double t = (x - c.x[k - 1]) / (c.x[k] - c.x[k - 1]);
  return c.y[k - 1] + t * (c.y[k] - c.y[k - 1]);
}

CurveError relative_error(const Curve& sim, const Curve& experiment) {
  CurveError e;
  double sum = 0;
  for (size_t k = 0; k < experiment.x.size(); ++k) {
    if (experiment.x[k] > sim.x.back() + 1e-12) continue;
    const double r = (interpolate(sim, experiment.x[k]) - experiment.y[k]) / experiment.y[k];
    sum += r * r;
    e.max_relative = std::max(e.max_relative, std::abs(r));
    ++e.points;
  }
  e.rms_relative = e.points ? std::sqrt(sum / double(e.points)) : 0.0;
  return e;
}

double water_height(const HostParticles& p, double x, double y, const SmoothingKernel<double>& kernel, double volume,
                    double z_floor, double z_top, double spacing) {
  const double support = kernel.support();
  std::vector<Vec3d> near;
  for (const Vec3f& q : p.pos)
    if (std::abs(q.x - x) < support && std::abs(q.y - y) < support) near.push_back({q.x, q.y, q.z});
  if (near.empty()) return 0.0;
  const double dz = 0.25 * spacing;
  double height = 0.0;
  for (double z = z_floor; z <= z_top + 1e-12; z += dz) {
    double fill = 0.0;
    for (const Vec3d& q : near) {
      const double r = length(Vec3d{x, y, z} - q);
      if (r < support) fill += volume * kernel.W(r);
    }
    if (fill >= 0.5) height = z - z_floor;
  }
  return height;
}

ObstacleForce obstacle_force(const TriangleMesh& mesh, const HostParticles& p, const std::vector<float>& pressure,
                             const SmoothingKernel<double>& kernel, Vec3d gravity, double spacing) {
  ObstacleForce out;
  if (p.pos.size() != pressure.size())
    throw std::invalid_argument("obstacle_force: one pressure per particle expected");
  const double support = kernel.support();
  // The particles near the mesh, binned in cells one support wide.
  Box box = bounds(mesh);
  box.min = box.min - Vec3d{support, support, support};
  box.max = box.max + Vec3d{support, support, support};
  const int nx = std::max(1, int(std::ceil((box.max.x - box.min.x) / support))),
            ny = std::max(1, int(std::ceil((box.max.y - box.min.y) / support))),
            nz = std::max(1, int(std::ceil((box.max.z - box.min.z) / support)));
  std::vector<std::vector<uint32_t>> cells(size_t(nx) * ny * nz);
  auto cell_of = [&](Vec3d x, int& i, int& j, int& k) {
    i = int(std::floor((x.x - box.min.x) / support));
    j = int(std::floor((x.y - box.min.y) / support));
    k = int(std::floor((x.z - box.min.z) / support));
    return i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz;
  };
  for (size_t f = 0; f < p.pos.size(); ++f) {
    int i, j, k;
    const Vec3d x{p.pos[f].x, p.pos[f].y, p.pos[f].z};
    if (cell_of(x, i, j, k)) cells[(size_t(k) * ny + j) * nx + i].push_back(uint32_t(f));
  }
  double area_all = 0, area_wet = 0;
  for (const auto& t : mesh.triangles) {
    const Vec3d a = mesh.vertices[t[0]], b = mesh.vertices[t[1]], c = mesh.vertices[t[2]];
    const Vec3d nA = cross(b - a, c - a) * 0.5;  // area times the outward normal
    const double longest = std::max({length(b - a), length(c - b), length(a - c)});
    const int m = std::max(1, int(std::ceil(longest / (0.5 * spacing))));
    // m^2 sub-triangles of equal area, sampled at their centroids.
    const Vec3d du = (b - a) * (1.0 / m), dv = (c - a) * (1.0 / m);
    for (int u = 0; u < m; ++u)
      for (int v = 0; u + v < m; ++v)
        for (int up = 0; up < (u + v + 1 < m ? 2 : 1); ++up) {
          const Vec3d x = up == 0 ? a + du * (u + 1.0 / 3.0) + dv * (v + 1.0 / 3.0)
                                  : a + du * (u + 2.0 / 3.0) + dv * (v + 2.0 / 3.0);
          double sw = 0, spw = 0, sgr = 0;
          int ci, cj, ck;
          cell_of(x, ci, cj, ck);
          for (int k = ck - 1; k <= ck + 1; ++k)
            for (int j = cj - 1; j <= cj + 1; ++j)
              for (int i = ci - 1; i <= ci + 1; ++i) {
                if (i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz) continue;
                for (const uint32_t f : cells[(size_t(k) * ny + j) * nx + i]) {
                  const Vec3d xf{p.pos[f].x, p.pos[f].y, p.pos[f].z};
                  const double r = length(x - xf);
                  if (r >= support) continue;
                  const double w = kernel.W(r);
                  sw += w;
                  spw += pressure[f] * w;
                  sgr += p.density[f] * dot(gravity, x - xf) * w;
                }
              }
          const double dA = 1.0 / (double(m) * m);  // share of the triangle
          area_all += dA * length(nA);
          if (sw <= 0) continue;
          area_wet += dA * length(nA);
          const double press = std::max(0.0, (spw + sgr) / sw);
          out.force -= nA * (press * dA);
        }
  }
  out.wetted = area_all > 0 ? area_wet / area_all : 0;
  return out;
}

}  // namespace sphray

namespace sphray {

namespace {

struct Lattice {
  int nx, ny, nz;
  size_t idx(int i, int j, int k) const { return (size_t(k) * ny + j) * nx + i; }
};

// Chebyshev dilation by `r` voxels, one axis at a time.
void dilate(const Lattice& L, std::vector<uint8_t>& m, int r) {
  std::vector<uint8_t> tmp(m.size());
  const int n[3] = {L.nx, L.ny, L.nz};
  for (int axis = 0; axis < 3; ++axis) {
    const size_t stride = axis == 0 ? 1 : axis == 1 ? size_t(L.nx) : size_t(L.nx) * L.ny;
#pragma omp parallel for schedule(static)
    for (int64_t v = 0; v < int64_t(m.size()); ++v) {
      const int c = axis == 0 ? int(v % L.nx) : axis == 1 ? int((v / L.nx) % L.ny) : int(v / (int64_t(L.nx) * L.ny));
      uint8_t out = 0;
      for (int d = -r; d <= r && !out; ++d) {
        const int cc = c + d;
        if (cc >= 0 && cc < n[axis]) out = m[size_t(v + int64_t(d) * int64_t(stride))];
      }
      tmp[size_t(v)] = out;
    }
    m.swap(tmp);
  }
}

struct SurfacePoints {
  std::vector<Vec3d> pts;
  std::vector<Vec3d> normals;     // unit field gradient at each point
  std::vector<uint32_t> offsets;  // per voxel bucket (floor of the point), size voxels + 1
  std::vector<uint32_t> sorted;   // point indices by bucket
};

SurfacePoints crossings(const Lattice& L, const std::vector<float>& f, float iso) {
  SurfacePoints s;
  for (int k = 0; k < L.nz; ++k)
    for (int j = 0; j < L.ny; ++j)
      for (int i = 0; i < L.nx; ++i) {
        const double f0 = f[L.idx(i, j, k)];
        const bool in0 = f0 >= iso;
        const int nb[3][3] = {{i + 1, j, k}, {i, j + 1, k}, {i, j, k + 1}};
        for (int a = 0; a < 3; ++a) {
          const int ii = nb[a][0], jj = nb[a][1], kk = nb[a][2];
          if (ii >= L.nx || jj >= L.ny || kk >= L.nz) continue;
          const double f1 = f[L.idx(ii, jj, kk)];
          if ((f1 >= iso) == in0) continue;
          const double t = (double(iso) - f0) / (f1 - f0);
          Vec3d p{i + 0.5, j + 0.5, k + 0.5};
          (a == 0 ? p.x : a == 1 ? p.y : p.z) += t;
          s.pts.push_back(p);
        }
      }
  // Normals: central-difference gradient at the voxel centres, trilinear between them.
  auto value = [&](int i, int j, int k) {
    i = std::clamp(i, 0, L.nx - 1); j = std::clamp(j, 0, L.ny - 1); k = std::clamp(k, 0, L.nz - 1);
    return double(f[L.idx(i, j, k)]);
  };
  auto grad_at = [&](int i, int j, int k) {
    return Vec3d{value(i + 1, j, k) - value(i - 1, j, k), value(i, j + 1, k) - value(i, j - 1, k),
                 value(i, j, k + 1) - value(i, j, k - 1)};
  };
  s.normals.resize(s.pts.size());
#pragma omp parallel for schedule(static)
  for (int64_t q = 0; q < int64_t(s.pts.size()); ++q) {
    const Vec3d p = s.pts[size_t(q)] - Vec3d{0.5, 0.5, 0.5};
    const int i0 = int(std::floor(p.x)), j0 = int(std::floor(p.y)), k0 = int(std::floor(p.z));
    const double tx = p.x - i0, ty = p.y - j0, tz = p.z - k0;
    Vec3d g{0, 0, 0};
    for (int c = 0; c < 8; ++c) {
      const int di = c & 1, dj = (c >> 1) & 1, dk = c >> 2;
      const double w = (di ? tx : 1 - tx) * (dj ? ty : 1 - ty) * (dk ? tz : 1 - tz);
      g += grad_at(i0 + di, j0 + dj, k0 + dk) * w;
    }
    const double len = length(g);
    s.normals[size_t(q)] = len > 0 ? g * (1.0 / len) : Vec3d{0, 0, 0};
  }
  const size_t voxels = size_t(L.nx) * L.ny * L.nz;
  s.offsets.assign(voxels + 1, 0);
  std::vector<size_t> bucket(s.pts.size());
  for (size_t q = 0; q < s.pts.size(); ++q) {
    const Vec3d& p = s.pts[q];
    const int i = std::min(L.nx - 1, int(p.x)), j = std::min(L.ny - 1, int(p.y)), k = std::min(L.nz - 1, int(p.z));
    bucket[q] = L.idx(i, j, k);
    ++s.offsets[bucket[q] + 1];
  }
  for (size_t v = 0; v < voxels; ++v) s.offsets[v + 1] += s.offsets[v];
  s.sorted.resize(s.pts.size());
  std::vector<uint32_t> fill(s.offsets.begin(), s.offsets.end() - 1);
  for (size_t q = 0; q < s.pts.size(); ++q) s.sorted[fill[bucket[q]]++] = uint32_t(q);
  return s;
}

// Distance from each point of `a` to the surface of `b`: the nearest point q of
// `b` (search shells of buckets around it until no closer point can be in the
// next shell), then the distance to the tangent plane at q (the surface
// points are samples about a voxel apart; the plane removes that sampling
// offset to second order in the curvature).
void match(const Lattice& L, const SurfacePoints& a, const SurfacePoints& b, double& sum, double& max_d,
           uint64_t& unmatched) {
  const double cap = FieldError::kMaxSurfaceDistance;
  const int rmax = int(cap) + 1;
  double s = 0, m = 0;
  uint64_t un = 0;
#pragma omp parallel for schedule(dynamic, 1024) reduction(+ : s, un) reduction(max : m)
  for (int64_t q = 0; q < int64_t(a.pts.size()); ++q) {
    const Vec3d p = a.pts[size_t(q)];
    const int ci = std::min(L.nx - 1, int(p.x)), cj = std::min(L.ny - 1, int(p.y)), ck = std::min(L.nz - 1, int(p.z));
    double best2 = cap * cap;
    bool found = false;
    uint32_t best = 0;
    for (int r = 0; r <= rmax; ++r) {
      for (int k = ck - r; k <= ck + r; ++k)
        for (int j = cj - r; j <= cj + r; ++j)
          for (int i = ci - r; i <= ci + r; ++i) {
            if (std::max({std::abs(i - ci), std::abs(j - cj), std::abs(k - ck)}) != r) continue;  // shell only
            if (i < 0 || j < 0 || k < 0 || i >= L.nx || j >= L.ny || k >= L.nz) continue;
            const size_t v = L.idx(i, j, k);
            for (uint32_t e = b.offsets[v]; e < b.offsets[v + 1]; ++e) {
              const Vec3d d = b.pts[b.sorted[e]] - p;
              const double d2 = dot(d, d);
              if (d2 <= best2) { best2 = d2; found = true; best = b.sorted[e]; }
            }
          }
      // Points in shell r + 1 are at least r voxels away.
      if (found && best2 <= double(r) * double(r)) break;
    }
    double d = cap;
    if (found) {
      d = std::sqrt(best2);
      const Vec3d nq = b.normals[best];
      if (d < 2.0 && length2(nq) > 0) d = std::min(d, std::abs(dot(p - b.pts[best], nq)));
    }
    if (!found) ++un;
    s += d;
    m = std::max(m, d);
  }
  sum += s;
  max_d = std::max(max_d, m);
  unmatched += un;
}

}  // namespace

FieldError compare_fields(int nx, int ny, int nz, const std::vector<float>& ref, const std::vector<float>& test,
                          float iso) {
  const Lattice L{nx, ny, nz};
  const size_t voxels = size_t(nx) * ny * nz;
  if (ref.size() != voxels || test.size() != voxels)
    throw std::invalid_argument("compare_fields: both fields must hold nx * ny * nz values");
  std::vector<uint8_t> band(voxels, 0);
#pragma omp parallel for schedule(static)
  for (int64_t v = 0; v < int64_t(voxels); ++v) {
    const int i = int(v % nx), j = int((v / nx) % ny), k = int(v / (int64_t(nx) * ny));
    const bool in = ref[size_t(v)] >= iso;
    const int nb[6][3] = {{i - 1, j, k}, {i + 1, j, k}, {i, j - 1, k}, {i, j + 1, k}, {i, j, k - 1}, {i, j, k + 1}};
    for (auto& c : nb) {
      if (c[0] < 0 || c[1] < 0 || c[2] < 0 || c[0] >= nx || c[1] >= ny || c[2] >= nz) continue;
      if ((ref[L.idx(c[0], c[1], c[2])] >= iso) != in) { band[size_t(v)] = 1; break; }
    }
  }
  dilate(L, band, 2);
  FieldError e;
  uint64_t nb = 0, mb = 0, mo = 0;
#pragma omp parallel for schedule(static) reduction(+ : nb, mb, mo)
  for (int64_t v = 0; v < int64_t(voxels); ++v) {
    const bool differs = (ref[size_t(v)] >= iso) != (test[size_t(v)] >= iso);
    if (band[size_t(v)]) {
      ++nb;
      if (differs) ++mb;
    } else if (differs) {
      ++mo;
    }
  }
  e.band = nb;
  e.misclassified_band = mb;
  e.misclassified_other = mo;

  const SurfacePoints a = crossings(L, ref, iso), b = crossings(L, test, iso);
  e.ref_points = a.pts.size();
  e.test_points = b.pts.size();
  double sum = 0;
  match(L, a, b, sum, e.max_distance, e.unmatched);
  match(L, b, a, sum, e.max_distance, e.unmatched);
  const double count = double(a.pts.size() + b.pts.size());
  e.mean_distance = count > 0 ? sum / count : 0.0;
  if (a.pts.empty() != b.pts.empty()) e.max_distance = FieldError::kMaxSurfaceDistance;
  return e;
}

}  // namespace sphray
