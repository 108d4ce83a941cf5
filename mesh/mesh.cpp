#include "mesh.h"

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <utility>

#include <tiny_obj_loader.h>

namespace sphray {

namespace {

[[noreturn]] void fail(const std::string& name, const std::string& what) { throw MeshError(name + ": " + what); }

}  // namespace

TriangleMesh read_obj(const std::string& path) {
  // tinyobjloader reads "nan" and "inf" as numbers it can parse (or as 0):
  // the vertex lines are checked for non-finite values (and overflow, which
  // strtod reads as infinite) first.
  {
    std::ifstream in(path);
    if (!in) fail(path, "cannot open the mesh file (missing or unreadable)");
    std::string line;
    size_t vertex = 0;
    while (std::getline(in, line)) {
      if (line.size() < 2 || line[0] != 'v' || (line[1] != ' ' && line[1] != '\t')) continue;
      ++vertex;
      std::istringstream fields(line.substr(2));
      for (std::string f; fields >> f;) {
        char* end = nullptr;
        const double x = std::strtod(f.c_str(), &end);
        if (end != f.c_str() && !std::isfinite(x)) {
          std::ostringstream os;
          os << "vertex " << vertex << " is not finite (" << line.substr(2) << ")";
          fail(path, os.str());
        }
      }
    }
  }
  tinyobj::ObjReaderConfig config;
  config.triangulate = true;
  config.vertex_color = false;
  config.mtl_search_path = "";
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path, config)) {
    std::string e = reader.Error();
    while (!e.empty() && (e.back() == '\n' || e.back() == '\r')) e.pop_back();
    fail(path, "not a readable OBJ mesh (" + (e.empty() ? std::string("parse error") : e) + ")");
  }
  TriangleMesh m;
  m.name = path;
  const auto& v = reader.GetAttrib().vertices;
  m.vertices.reserve(v.size() / 3);
  for (size_t i = 0; i + 2 < v.size(); i += 3) {
    const Vec3d p{double(v[i]), double(v[i + 1]), double(v[i + 2])};
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      std::ostringstream os;
      os << "vertex " << i / 3 + 1 << " is not finite (" << p.x << ", " << p.y << ", " << p.z << ")";
      fail(path, os.str());
    }
    m.vertices.push_back(p);
  }
  for (const auto& shape : reader.GetShapes()) {
    const auto& idx = shape.mesh.indices;
    size_t at = 0;
    for (const auto nv : shape.mesh.num_face_vertices) {
      if (nv == 3) {
        std::array<uint32_t, 3> t{};
        for (int k = 0; k < 3; ++k) {
          const int vi = idx[at + k].vertex_index;
          if (vi < 0 || size_t(vi) >= m.vertices.size()) fail(path, "a face refers to a vertex that does not exist");
          t[k] = uint32_t(vi);
        }
        m.triangles.push_back(t);
      }
      at += nv;
    }
  }
  if (m.triangles.empty()) fail(path, "the mesh has no triangles");
  return m;
}

std::array<Vec3d, 3> rotation_rows(Vec3d r) {
  const double k = M_PI / 180.0;
  std::array<Vec3d, 3> rows;
  rotation_rows_xyz(r.x * k, r.y * k, r.z * k, rows.data());
  return rows;
}

TriangleMesh placed(const TriangleMesh& m, const Placement& p) {
  const auto R = rotation_rows(p.rotate_deg);
  TriangleMesh out = m;
  for (auto& v : out.vertices) {
    const Vec3d s{v.x * p.scale.x, v.y * p.scale.y, v.z * p.scale.z};
    v = Vec3d{dot(R[0], s), dot(R[1], s), dot(R[2], s)} + p.translate;
  }
  // A mirroring scale (an odd count of negative factors) turns the winding inside out.
  if (p.scale.x * p.scale.y * p.scale.z < 0) flip(out);
  return out;
}

void check_mesh(const TriangleMesh& m, double min_area) {
  if (m.triangles.empty()) fail(m.name, "the mesh has no triangles");
  for (size_t i = 0; i < m.vertices.size(); ++i) {
    const Vec3d p = m.vertices[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      std::ostringstream os;
      os << "vertex " << i + 1 << " is not finite";
      fail(m.name, os.str());
    }
  }
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (size_t t = 0; t < m.triangles.size(); ++t) {
    const auto& tr = m.triangles[t];
    for (int k = 0; k < 3; ++k)
      if (tr[k] >= m.vertices.size()) fail(m.name, "triangle " + std::to_string(t + 1) + " refers to a vertex that does not exist");
    const double A = triangle_area(m.vertices[tr[0]], m.vertices[tr[1]], m.vertices[tr[2]]);
    if (!(A >= min_area)) {
      std::ostringstream os;
      os << "triangle " << t + 1 << " is degenerate (area " << A << " m^2, below " << min_area << ")";
      fail(m.name, os.str());
    }
    for (int k = 0; k < 3; ++k) {
      const uint32_t u = tr[k], w = tr[(k + 1) % 3];
      ++edges[{std::min(u, w), std::max(u, w)}];
    }
  }
  size_t open = 0, non_manifold = 0;
  for (const auto& [e, n] : edges) {
    if (n == 1) ++open;
    else if (n > 2) ++non_manifold;
  }
  if (open || non_manifold) {
    std::ostringstream os;
    os << "the mesh is not closed: " << open << " edges belong to one triangle only and " << non_manifold
       << " to more than two (an obstacle must enclose a volume; close its holes or give thin parts a thickness)";
    fail(m.name, os.str());
  }
}

Box bounds(const TriangleMesh& m) {
  Box b{{1e300, 1e300, 1e300}, {-1e300, -1e300, -1e300}};
  for (const auto& v : m.vertices) {
    b.min = {std::min(b.min.x, v.x), std::min(b.min.y, v.y), std::min(b.min.z, v.z)};
    b.max = {std::max(b.max.x, v.x), std::max(b.max.y, v.y), std::max(b.max.z, v.z)};
  }
  return b;
}

double area(const TriangleMesh& m) {
  double s = 0;
  for (const auto& t : m.triangles) s += triangle_area(m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]);
  return s;
}

double signed_volume(const TriangleMesh& m) {
  double s = 0;
  for (const auto& t : m.triangles) s += dot(m.vertices[t[0]], cross(m.vertices[t[1]], m.vertices[t[2]]));
  return s / 6.0;
}

void flip(TriangleMesh& m) {
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
}

TriangleMesh box_mesh(const Box& b, const std::string& name) {
  TriangleMesh m;
  m.name = name;
  for (int k = 0; k < 8; ++k)
    m.vertices.push_back({k & 1 ? b.max.x : b.min.x, k & 2 ? b.max.y : b.min.y, k & 4 ? b.max.z : b.min.z});
  // Two triangles per face, counter-clockwise seen from outside.
  const uint32_t q[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : q) {
    m.triangles.push_back({f[0], f[1], f[2]});
    m.triangles.push_back({f[0], f[2], f[3]});
  }
  return m;
}

TriangleMesh sphere_mesh(Vec3d centre, double radius, int levels, const std::string& name) {
  TriangleMesh m;
  m.name = name;
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3d> v = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                          {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  std::vector<std::array<uint32_t, 3>> f = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                            {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                            {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (auto& p : v) p = p * (1.0 / length(p));
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto middle = [&](uint32_t a, uint32_t b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      Vec3d p = v[a] + v[b];
      v.push_back(p * (1.0 / length(p)));
      return mid[key] = uint32_t(v.size() - 1);
    };
    std::vector<std::array<uint32_t, 3>> next;
    for (const auto& t : f) {
      const uint32_t a = middle(t[0], t[1]), b = middle(t[1], t[2]), c = middle(t[2], t[0]);
      next.push_back({t[0], a, c});
      next.push_back({t[1], b, a});
      next.push_back({t[2], c, b});
      next.push_back({a, b, c});
    }
    f.swap(next);
  }
  for (const auto& p : v) m.vertices.push_back(centre + p * radius);
  m.triangles = f;
  return m;
}

void write_obj(const TriangleMesh& m, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw MeshError(path + ": cannot write the mesh file");
  out.precision(9);
  for (const auto& v : m.vertices) out << "v " << v.x << ' ' << v.y << ' ' << v.z << '\n';
  for (const auto& t : m.triangles) out << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  if (!out) throw MeshError(path + ": writing the mesh file failed");
}

}  // namespace sphray
