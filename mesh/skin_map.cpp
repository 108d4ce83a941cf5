#include "skin_map.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <utility>

#include <Eigen/Sparse>

#include "bvh.h"

namespace sphray {

namespace {

Vec3d face_normal(const TriangleMesh& m, size_t t, double* twice_area = nullptr) {
  const auto& tri = m.triangles[t];
  const Vec3d n = cross(m.vertices[tri[1]] - m.vertices[tri[0]], m.vertices[tri[2]] - m.vertices[tri[0]]);
  const double len = std::sqrt(dot(n, n));
  if (twice_area) *twice_area = len;
  return n * (1.0 / len);
}

// The enclosed volume's centroid (tetrahedra on the origin), the mesh's
// triangles over the vertex positions x.
Vec3d volume_centroid_of(const TriangleMesh& m, const std::vector<Vec3d>& x) {
  Vec3d sum{0, 0, 0};
  double vol = 0;
  for (const auto& t : m.triangles) {
    const Vec3d a = x[t[0]], b = x[t[1]], c = x[t[2]];
    const double v = dot(a, cross(b, c)) / 6.0;
    sum = sum + (a + b + c) * (v / 4.0);
    vol += v;
  }
  return sum * (1.0 / vol);
}

const Vec3d kTu[6] = {{0, 1, 0}, {0, 1, 0}, {1, 0, 0}, {1, 0, 0}, {1, 0, 0}, {1, 0, 0}};
const Vec3d kTv[6] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 0, 1}, {0, 1, 0}, {0, 1, 0}};
const Vec3d kAxis[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

// The ray from the origin along d against the triangle (a, b, c), in double:
// barycentrics (of b and c) and whether the ray's line meets it.
bool ray_barycentrics(Vec3d d, Vec3d a, Vec3d b, Vec3d c, double& w1, double& w2) {
  const Vec3d e1 = b - a, e2 = c - a;
  const Vec3d p = cross(d, e2);
  const double det = dot(e1, p);
  if (std::abs(det) < 1e-300) return false;
  const Vec3d s = a * -1.0;
  w1 = dot(s, p) / det;
  const Vec3d q = cross(s, e1);
  w2 = dot(d, q) / det;
  return true;
}

}  // namespace

size_t folded_triangles(const TriangleMesh& m, const std::vector<Vec3d>& u) {
  size_t folded = 0;
  for (const auto& t : m.triangles) {
    const Vec3d a = u[t[0]], b = u[t[1]], c = u[t[2]];
    if (dot(cross(b - a, c - a), a + b + c) <= 0.0) ++folded;
  }
  return folded;
}

SphereEmbedding embed_on_sphere(const TriangleMesh& m, int max_iterations) {
  SphereEmbedding e;
  const size_t nv = m.vertices.size();
  auto project = [&](const std::vector<Vec3d>& x) {
    e.centre = volume_centroid_of(m, x);
    e.u.resize(nv);
    for (size_t i = 0; i < nv; ++i) {
      const Vec3d r = x[i] - e.centre;
      if (dot(r, r) == 0.0) throw MeshError(m.name + ": a vertex lies at the mesh's centroid; it has no direction");
      e.u[i] = normalized(r);
    }
    return folded_triangles(m, e.u);
  };
  size_t folded = project(m.vertices);
  if (folded == 0) return e;

  // Conformalized mean-curvature flow (Kazhdan, Solomon & Ben-Chen, "Can
  // Mean-Curvature Flow be Modified to be Non-singular?", 2012): implicit
  // steps (M_t + tau L) x_{t+1} = M_t x_t with the cotangent Laplacian L of
  // the input and the lumped mass M_t of the current shape; a genus-0 surface
  // rounds toward a sphere, conformally, and its central projection stops
  // folding. Scaled to unit area each step, so that tau is relative.
  using Sparse = Eigen::SparseMatrix<double>;
  std::vector<Eigen::Triplet<double>> lt;
  lt.reserve(12 * m.size());
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = t[k], j = t[(k + 1) % 3], o = t[(k + 2) % 3];
      const Vec3d a = m.vertices[i] - m.vertices[o], b = m.vertices[j] - m.vertices[o];
      const double cot = dot(a, b) / std::max(length(cross(a, b)), 1e-300);
      const double w = 0.5 * cot;
      lt.emplace_back(i, j, -w);
      lt.emplace_back(j, i, -w);
      lt.emplace_back(i, i, w);
      lt.emplace_back(j, j, w);
    }
  const Eigen::Index size = Eigen::Index(nv);
  Sparse L(size, size);
  L.setFromTriplets(lt.begin(), lt.end());
  std::vector<Vec3d> x = m.vertices;
  auto normalise_shape = [&] {
    double total = 0;
    Vec3d c{0, 0, 0};
    for (const auto& t : m.triangles) {
      const double a = triangle_area(x[t[0]], x[t[1]], x[t[2]]);
      total += a;
      c = c + (x[t[0]] + x[t[1]] + x[t[2]]) * (a / 3.0);
    }
    c = c * (1.0 / total);
    const double scale = 1.0 / std::sqrt(total);
    for (Vec3d& v : x) v = (v - c) * scale;
  };
  normalise_shape();
  const double tau = 1e-3;
  Eigen::SimplicialLDLT<Sparse> solver;
  Eigen::MatrixXd rhs(size, 3), next;
  while (folded > 0 && e.iterations < max_iterations) {
    std::vector<double> mass(nv, 0.0);
    for (const auto& t : m.triangles) {
      const double a = triangle_area(x[t[0]], x[t[1]], x[t[2]]);
      for (uint32_t v : t) mass[v] += a / 3.0;
    }
    Sparse A = L * tau;
    for (size_t i = 0; i < nv; ++i) {
      A.coeffRef(Eigen::Index(i), Eigen::Index(i)) += mass[i];
      rhs(Eigen::Index(i), 0) = mass[i] * x[i].x;
      rhs(Eigen::Index(i), 1) = mass[i] * x[i].y;
      rhs(Eigen::Index(i), 2) = mass[i] * x[i].z;
    }
    solver.compute(A);
    if (solver.info() != Eigen::Success) break;
    next = solver.solve(rhs);
    for (size_t i = 0; i < nv; ++i) x[i] = {next(Eigen::Index(i), 0), next(Eigen::Index(i), 1), next(Eigen::Index(i), 2)};
    normalise_shape();
    ++e.iterations;
    folded = project(x);
  }
  if (folded > 0)
    throw MeshError(m.name + ": cannot be mapped one to one onto a sphere (" + std::to_string(folded) +
                    " triangles still folded after " + std::to_string(e.iterations) +
                    " steps of conformal flow); a skin needs a closed genus-0 mesh");
  return e;
}

CubeCoord cube_coord(Vec3d d) {
  const double ax = std::abs(d.x), ay = std::abs(d.y), az = std::abs(d.z);
  CubeCoord c;
  if (ax >= ay && ax >= az) c.face = d.x >= 0 ? 0 : 1;
  else if (ay >= az) c.face = d.y >= 0 ? 2 : 3;
  else c.face = d.z >= 0 ? 4 : 5;
  const double major = std::abs(dot(d, kAxis[c.face]));
  c.a = dot(d, kTu[c.face]) / major;
  c.b = dot(d, kTv[c.face]) / major;
  return c;
}

Vec3d cube_direction(int face, double a, double b) { return kAxis[face] + kTu[face] * a + kTv[face] * b; }

uint32_t SkinMap::texel_of(Vec3d d) const {
  const CubeCoord c = cube_coord(d);
  const int i = std::clamp(int(std::floor((c.a + 1.0) * 0.5 * n)), 0, n - 1);
  const int j = std::clamp(int(std::floor((c.b + 1.0) * 0.5 * n)), 0, n - 1);
  return index(c.face, i, j);
}

double SkinMap::sample(const std::vector<float>& value, Vec3d d) const {
  const CubeCoord c = cube_coord(d);
  const double x = std::clamp((c.a + 1.0) * 0.5 * n - 0.5, 0.0, double(n - 1));
  const double y = std::clamp((c.b + 1.0) * 0.5 * n - 0.5, 0.0, double(n - 1));
  const int i0 = std::min(int(x), n - 2 < 0 ? 0 : n - 2), j0 = std::min(int(y), n - 2 < 0 ? 0 : n - 2);
  const double fx = x - i0, fy = y - j0;
  const auto v = [&](int i, int j) { return double(value[index(c.face, i, j)]); };
  return (1 - fy) * ((1 - fx) * v(i0, j0) + fx * v(i0 + 1, j0)) + fy * ((1 - fx) * v(i0, j0 + 1) + fx * v(i0 + 1, j0 + 1));
}

SkinMap make_skin_map(const TriangleMesh& m, int n, SphereEmbedding embedding) {
  if (n < 2) throw MeshError(m.name + ": a skin needs at least 2 texels along a cube edge");
  SkinMap s;
  s.n = n;
  s.embedding = embedding.u.empty() ? embed_on_sphere(m) : std::move(embedding);
  const std::vector<Vec3d>& u = s.embedding.u;

  // The embedded mesh's flat triangles, through a BVH: a texel's ray meets one.
  std::vector<Vec3f> uf(u.size());
  for (size_t i = 0; i < u.size(); ++i) uf[i] = to_f(u[i]);
  std::vector<uint32_t> idx;
  idx.reserve(3 * m.size());
  for (const auto& t : m.triangles) idx.insert(idx.end(), t.begin(), t.end());
  const std::unique_ptr<Bvh> tree = make_cpu_bvh(uf, idx);
  const MeshView view = tree->view();
  const std::vector<uint32_t> order = tree->input_order();

  const size_t texels = size_t(6) * n * n;
  s.point.resize(texels);
  s.normal.resize(texels);
  std::vector<CubeCoord> centre(texels);
  for (int f = 0; f < 6; ++f)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const uint32_t k = s.index(f, i, j);
        CubeCoord c{f, -1.0 + (i + 0.5) * 2.0 / n, -1.0 + (j + 0.5) * 2.0 / n};
        centre[k] = c;
        const Vec3d d = normalized(cube_direction(f, c.a, c.b));
        float hit_s = 0;
        uint32_t slot = 0;
        if (!first_hit(view, Vec3f{0, 0, 0}, to_f(d), 4.0f, hit_s, slot))
          throw MeshError(m.name + ": a texel's ray meets no triangle of the spherical embedding");
        const size_t t = order[slot];
        const auto& tri = m.triangles[t];
        double w1 = 0, w2 = 0;
        ray_barycentrics(d, u[tri[0]], u[tri[1]], u[tri[2]], w1, w2);
        // Rounding at a shared edge may leave a barycentric a hair outside.
        w1 = std::clamp(w1, 0.0, 1.0);
        w2 = std::clamp(w2, 0.0, 1.0 - w1);
        s.point[k] = m.vertices[tri[0]] * (1.0 - w1 - w2) + m.vertices[tri[1]] * w1 + m.vertices[tri[2]] * w2;
        s.normal[k] = face_normal(m, t);
      }

  const int di[kSkinNeighbours] = {1, -1, 0, 0, 1, -1, 1, -1};
  const int dj[kSkinNeighbours] = {0, 0, 1, -1, 1, 1, -1, -1};
  s.neighbour.resize(texels);
  s.distance.resize(texels);
  double spacing_sum = 0;
  for (int f = 0; f < 6; ++f)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const uint32_t k = s.index(f, i, j);
        for (int q = 0; q < kSkinNeighbours; ++q) {
          const int ii = i + di[q], jj = j + dj[q];
          uint32_t nb;
          if (ii >= 0 && ii < n && jj >= 0 && jj < n) {
            nb = s.index(f, ii, jj);
          } else {
            // Past the face's edge: the texel of the neighbouring face that
            // the face's plane, extended, points at.
            const double a = centre[k].a + di[q] * 2.0 / n, b = centre[k].b + dj[q] * 2.0 / n;
            nb = s.texel_of(cube_direction(f, a, b));
          }
          s.neighbour[k][q] = nb;
          const Vec3d r = s.point[nb] - s.point[k];
          s.distance[k][q] = nb == k ? 0.0 : std::sqrt(dot(r, r));
          if (q < 4) spacing_sum += s.distance[k][q];
        }
      }
  s.mean_spacing = spacing_sum / double(4 * texels);
  return s;
}

SkinSurface skin_surface(const TriangleMesh& m, const SphereEmbedding& e, double max_edge, int max_levels) {
  SkinSurface out;
  out.mesh = m;
  std::vector<Vec3d> chord = e.u;  // points on the embedded mesh's flat triangles
  auto longest_edge = [](const TriangleMesh& t) {
    double longest = 0;
    for (const auto& tri : t.triangles)
      for (int k = 0; k < 3; ++k) {
        const Vec3d r = t.vertices[tri[(k + 1) % 3]] - t.vertices[tri[k]];
        longest = std::max(longest, dot(r, r));
      }
    return std::sqrt(longest);
  };
  for (int level = 0; level < max_levels && longest_edge(out.mesh) > max_edge; ++level) {
    TriangleMesh next;
    next.name = out.mesh.name;
    next.vertices = out.mesh.vertices;
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      const uint32_t k = uint32_t(next.vertices.size());
      next.vertices.push_back((next.vertices[a] + next.vertices[b]) * 0.5);
      chord.push_back((chord[a] + chord[b]) * 0.5);
      mid.emplace(key, k);
      return k;
    };
    next.triangles.reserve(4 * out.mesh.size());
    for (const auto& t : out.mesh.triangles) {
      const uint32_t ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      next.triangles.push_back({t[0], ab, ca});
      next.triangles.push_back({ab, t[1], bc});
      next.triangles.push_back({ca, bc, t[2]});
      next.triangles.push_back({ab, bc, ca});
    }
    out.mesh = std::move(next);
  }
  out.direction.resize(chord.size());
  for (size_t i = 0; i < chord.size(); ++i) out.direction[i] = normalized(chord[i]);
  out.normal.assign(out.mesh.vertices.size(), Vec3d{0, 0, 0});
  for (size_t t = 0; t < out.mesh.size(); ++t) {
    double twice_area = 0;
    const Vec3d n = face_normal(out.mesh, t, &twice_area);
    for (uint32_t v : out.mesh.triangles[t]) out.normal[v] = out.normal[v] + n * twice_area;
  }
  for (Vec3d& n : out.normal) n = normalized(n);
  return out;
}

}  // namespace sphray
