// Triangle meshes on the host: reading (OBJ through tinyobjloader), placing
// (scale, rotation, translation) and the checks a mesh must pass before it
// becomes an obstacle: not empty, finite, no degenerate triangle, closed
// (every edge shared by exactly two triangles). Errors name the file.
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/vec.h"

namespace sphray {

// A mesh that cannot be used; the message names the file and the problem.
struct MeshError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct TriangleMesh {
  std::string name;  // the file it came from (for messages)
  std::vector<Vec3d> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
  size_t size() const { return triangles.size(); }
};

// Reads every face of an OBJ file (polygons triangulated by the loader);
// throws MeshError for a missing or unreadable file, a parse error, an empty
// mesh or a non-finite vertex.
TriangleMesh read_obj(const std::string& path);

// Body-to-world placement: x_world = R (s * x_body) + t, R from rotations
// about x, then y, then z by the given angles [degrees].
struct Placement {
  Vec3d scale{1, 1, 1};
  Vec3d rotate_deg{0, 0, 0};
  Vec3d translate{0, 0, 0};
};
// The rotation's rows (R = rows), for host and device transforms (Frame).
std::array<Vec3d, 3> rotation_rows(Vec3d rotate_deg);
TriangleMesh placed(const TriangleMesh& m, const Placement& p);

// Throws MeshError naming m.name: no triangles, a non-finite vertex, an index
// out of range, a triangle of area below `min_area` (degenerate), an edge not
// shared by exactly two triangles (open or non-manifold).
void check_mesh(const TriangleMesh& m, double min_area);

inline double triangle_area(Vec3d a, Vec3d b, Vec3d c) { return 0.5 * length(cross(b - a, c - a)); }
Box bounds(const TriangleMesh& m);
double area(const TriangleMesh& m);
// Enclosed volume (divergence theorem), positive for outward-facing triangles.
double signed_volume(const TriangleMesh& m);
// The same mesh with every triangle's winding reversed.
void flip(TriangleMesh& m);

// Closed meshes built in code: an axis-aligned box (outward winding), an
// icosphere of `levels` subdivisions.
TriangleMesh box_mesh(const Box& b, const std::string& name = "box");
TriangleMesh sphere_mesh(Vec3d centre, double radius, int levels, const std::string& name = "sphere");
void write_obj(const TriangleMesh& m, const std::string& path);

}  // namespace sphray
