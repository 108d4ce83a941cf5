// Triangle meshes and their BVH: reading and checking meshes, and every BVH
// query against a brute-force loop over all triangles in double precision.
#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include "catch.h"
#include "helpers.h"
#include "mesh/bvh.h"
#include "mesh/mesh.h"
#include "pipeline/setup.h"
#include "sph/obstacles.h"

using namespace sphray;

namespace {

// The tree of a mesh on the CPU (the solver's conversion, mesh_input).
std::unique_ptr<Bvh> cpu_bvh(const TriangleMesh& m) {
  const MeshInput in = mesh_input(m);
  return make_cpu_bvh(in.vertices, in.indices);
}

// Double-precision ray-triangle parameter, or -1.
double ray_triangle(const TriangleMesh& m, size_t t, Vec3d o, Vec3d d) {
  const Vec3d a = m.vertices[m.triangles[t][0]], b = m.vertices[m.triangles[t][1]], c = m.vertices[m.triangles[t][2]];
  const Vec3d e1 = b - a, e2 = c - a, p = cross(d, e2);
  const double det = dot(e1, p);
  if (det == 0) return -1;
  const Vec3d q = o - a;
  const double u = dot(q, p) / det, v = dot(d, cross(q, e1)) / det;
  if (u < 0 || v < 0 || u + v > 1) return -1;
  const double s = dot(e2, cross(q, e1)) / det;
  return s > 0 ? s : -1;
}

double point_triangle2(const TriangleMesh& m, size_t t, Vec3d p) {
  // Dense barycentric sampling plus the edges, fine enough to compare at 1e-3 of the size.
  const Vec3d a = m.vertices[m.triangles[t][0]], b = m.vertices[m.triangles[t][1]], c = m.vertices[m.triangles[t][2]];
  const Vec3d n0 = cross(b - a, c - a);
  const Vec3d n = n0 * (1.0 / length(n0));
  const Vec3d q = p - n * dot(p - a, n);  // projection onto the plane
  const Vec3d v0 = b - a, v1 = c - a, v2 = q - a;
  const double d00 = dot(v0, v0), d01 = dot(v0, v1), d11 = dot(v1, v1), d20 = dot(v2, v0), d21 = dot(v2, v1);
  const double den = d00 * d11 - d01 * d01;
  const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
  if (v >= 0 && w >= 0 && v + w <= 1) return length2(p - q);
  auto seg = [&](Vec3d s0, Vec3d s1) {
    const Vec3d e = s1 - s0;
    const double u = std::clamp(dot(p - s0, e) / dot(e, e), 0.0, 1.0);
    return length2(p - (s0 + e * u));
  };
  return std::min({seg(a, b), seg(b, c), seg(c, a)});
}

// Whether a message holds every piece.
struct Has {
  std::vector<std::string> parts;
};
Has has(const std::string& p) { return {{p}}; }
Has operator&&(Has a, const Has& b) {
  a.parts.insert(a.parts.end(), b.parts.begin(), b.parts.end());
  return a;
}
bool holds(const std::string& msg, const Has& h) {
  for (const auto& p : h.parts)
    if (msg.find(p) == std::string::npos) return false;
  return true;
}
#define CHECK_ALL(msg, h) \
  do {                    \
    const std::string m_ = (msg); \
    INFO(m_);             \
    CHECK(holds(m_, h));  \
  } while (0)

std::string write_text(const test::TempDir& dir, const std::string& name, const std::string& text) {
  const std::string path = dir.path() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

std::string mesh_error(const std::string& path) {
  try {
    check_mesh(read_obj(path), 1e-12);
  } catch (const MeshError& e) {
    return e.what();
  }
  return {};
}

}  // namespace

TEST_CASE("built-in meshes are closed, with the volume and area of their shapes", "[mesh][cpu]") {
  const TriangleMesh box = box_mesh({{0, 0, 0}, {1, 2, 3}});
  check_mesh(box, 1e-12);
  CHECK(signed_volume(box) == Approx(6.0));
  CHECK(area(box) == Approx(22.0));
  const TriangleMesh s = sphere_mesh({1, 1, 1}, 0.5, 4);
  check_mesh(s, 1e-12);
  // An inscribed polyhedron of 5120 faces: volume within 0.3% of the sphere's.
  CHECK(signed_volume(s) == Approx(4.0 / 3.0 * M_PI * 0.125).epsilon(3e-3));
  TriangleMesh f = box;
  flip(f);
  CHECK(signed_volume(f) == Approx(-6.0));
}

TEST_CASE("placing a mesh scales, rotates about x, y, z and translates", "[mesh][cpu]") {
  const TriangleMesh box = box_mesh({{0, 0, 0}, {1, 1, 1}});
  Placement p;
  p.scale = {2, 1, 1};
  p.rotate_deg = {0, 0, 90};
  p.translate = {5, 0, 0};
  const TriangleMesh m = placed(box, p);
  // (2, 0, 0) scaled -> rotated 90 deg about z -> (0, 2, 0) -> translated (5, 2, 0).
  const Box b = bounds(m);
  CHECK(b.min.x == Approx(4.0));
  CHECK(b.max.x == Approx(5.0));
  CHECK(b.max.y == Approx(2.0));
  CHECK(signed_volume(m) == Approx(2.0));
  p.scale = {-1, 1, 1};  // a mirror keeps the volume positive (winding flipped)
  CHECK(signed_volume(placed(box, p)) == Approx(1.0));
}

TEST_CASE("bad meshes are refused naming the file and the problem", "[mesh][cpu]") {
  test::TempDir dir;
  CHECK_ALL(mesh_error(dir.path() + "/none.obj"), has("none.obj") &&
                                                      has("cannot open"));
  CHECK_ALL(mesh_error(write_text(dir, "empty.obj", "# nothing\n")), has("no triangles"));
  CHECK_ALL(mesh_error(write_text(dir, "nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")),
             has("nan.obj") && has("not finite"));
  CHECK_ALL(mesh_error(write_text(dir, "open.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")),
             has("not closed"));
  CHECK_ALL(mesh_error(write_text(dir, "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n")),
             has("degenerate"));
  // A mesh written and read back is the same mesh.
  const std::string path = dir.path() + "/s.obj";
  write_obj(sphere_mesh({0, 0, 0}, 1, 1), path);
  const TriangleMesh back = read_obj(path);
  CHECK(back.size() == 80);
  check_mesh(back, 1e-12);
}

TEST_CASE("BVH queries match a brute-force loop over every triangle", "[mesh][cpu]") {
  // A sphere and a box together: overlapping, many equal Morton codes on the box's faces.
  TriangleMesh m = sphere_mesh({0.5, 0.5, 0.5}, 0.4, 3);
  const TriangleMesh b = box_mesh({{0.2, 0.3, 0.1}, {0.9, 0.35, 0.8}});
  const uint32_t base = uint32_t(m.vertices.size());
  m.vertices.insert(m.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (auto t : b.triangles) m.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  const auto bvh = cpu_bvh(m);
  const MeshView v = bvh->view();
  const std::vector<uint32_t> order = bvh->input_order();
  REQUIRE(v.num_tris == m.size());
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.2, 1.2), dir(-1, 1);
  int hits = 0;
  for (int k = 0; k < 2000; ++k) {
    const Vec3d o{u(rng), u(rng), u(rng)};
    Vec3d d{dir(rng), dir(rng), dir(rng)};
    d = d * (1.0 / length(d));
    double best = 1e30;
    size_t best_t = 0;
    int crossings = 0;
    for (size_t t = 0; t < m.size(); ++t) {
      const double s = ray_triangle(m, t, o, d);
      if (s > 0) { ++crossings; if (s < best) { best = s; best_t = t; } }
    }
    float s = 0;
    uint32_t slot = 0;
    const bool hit = first_hit(v, {float(o.x), float(o.y), float(o.z)}, {float(d.x), float(d.y), float(d.z)}, 10.0f, s, slot);
    CHECK(hit == (best < 10));
    if (hit && best < 10) {
      ++hits;
      CHECK(s == Approx(best).margin(1e-5));
      if (std::abs(s - best) > 1e-4) CHECK(order[slot] == best_t);
    }
    CHECK(int(count_crossings(v, {float(o.x), float(o.y), float(o.z)}, {float(d.x), float(d.y), float(d.z)})) == crossings);
    // Nearest point, within a radius that sometimes holds nothing.
    double near2 = 1e30;
    for (size_t t = 0; t < m.size(); ++t) near2 = std::min(near2, point_triangle2(m, t, o));
    uint32_t near_slot = 0;
    const float r2 = 0.04f;
    const float got = nearest_distance2(v, {float(o.x), float(o.y), float(o.z)}, r2, near_slot);
    if (near2 < r2 * 0.999) CHECK(std::sqrt(got) == Approx(std::sqrt(near2)).margin(2e-6));
    else if (near2 > r2 * 1.001) CHECK(got == r2);
  }
  CHECK(hits > 300);
}

TEST_CASE("a refit BVH answers for the moved vertices", "[mesh][cpu]") {
  const TriangleMesh m = sphere_mesh({0, 0, 0}, 1, 2);
  const auto bvh = cpu_bvh(m);
  auto verts = mesh_input(m).vertices;
  for (auto& p : verts) p = p * 2.0f + Vec3f{3, 0, 0};  // scaled and moved
  bvh->refit(verts);
  float s = 0;
  uint32_t slot = 0;
  REQUIRE(first_hit(bvh->view(), {0, 0, 0}, {1, 0, 0}, 100.0f, s, slot));
  CHECK(s == Approx(1.0).margin(0.02));  // the near side of the sphere of radius 2 at x = 3
  CHECK(count_crossings(bvh->view(), {3, 0.01f, 0.02f}, {0.3f, 0.5f, 0.8f}) == 1);  // from inside: once
  const MeshView v = bvh->view();
  CHECK(v.lo.x == Approx(1.0f));
  CHECK(v.hi.x == Approx(5.0f));
}

namespace {

// The shading normal at the hits of rays from outside toward the centre of
// a mesh around the origin: its angle to the direction of the hit point
// (the sphere's normal) and to the flat triangle's normal, in degrees,
// averaged over 2,000 rays.
struct NormalErrors {
  double smooth = 0, flat = 0, smooth_to_face = 0;
};
NormalErrors normal_errors(const MeshView& v) {
  std::mt19937 rng(7);
  std::normal_distribution<float> g(0.0f, 1.0f);
  auto deg = [](Vec3f a, Vec3f b) { return std::acos(std::fmin(1.0, double(dot(a, b)))) * 180.0 / M_PI; };
  NormalErrors e;
  const int n = 2000;
  for (int k = 0; k < n; ++k) {
    const Vec3f u = normalized(Vec3f{g(rng), g(rng), g(rng)});
    const Vec3f o = u * 3.0f, d = -1.0f * u;
    float s = 0;
    uint32_t slot = 0;
    REQUIRE(first_hit(v, o, d, 10.0f, s, slot));
    const Vec3f p = o + s * d;
    const Vec3f ns = shading_normal(v.tris[slot], p), nf = triangle_normal(v.tris[slot]);
    e.smooth += deg(ns, normalized(p)) / n;
    e.flat += deg(nf, normalized(p)) / n;
    e.smooth_to_face += deg(ns, nf) / n;
  }
  return e;
}

}  // namespace

TEST_CASE("meshes shade smooth within the crease angle and keep their edges", "[mesh][cpu]") {
  // The packing: 16 bits per octahedral coordinate, under 0.01 degrees.
  std::mt19937 rng(3);
  std::normal_distribution<float> g(0.0f, 1.0f);
  double worst = 0;
  for (int k = 0; k < 10000; ++k) {
    const Vec3f n = normalized(Vec3f{g(rng), g(rng), g(rng)});
    const Vec3f m = unpack_normal(pack_normal(n));
    const Vec3d a{m.x, m.y, m.z}, b{n.x, n.y, n.z};
    worst = std::max(worst, std::atan2(length(cross(a, b)), dot(a, b)) * 180.0 / M_PI);
  }
  CHECK(worst < 0.01);
  for (const Vec3f n : {Vec3f{0, 0, 1}, Vec3f{0, 0, -1}, Vec3f{1, 0, 0}, Vec3f{0, -1, 0}})
    CHECK(dot(unpack_normal(pack_normal(n)), n) > 0.99999f);
  // A sphere of 320 triangles: the interpolated normal is the sphere's far
  // better than the triangle's.
  const TriangleMesh ball = sphere_mesh({0, 0, 0}, 1, 2);
  const auto bvh = cpu_bvh(ball);
  const NormalErrors e = normal_errors(bvh->view());
  INFO("sphere: smooth " << e.smooth << " deg, flat " << e.flat << " deg from the sphere's normal");
  CHECK(e.smooth < 0.3 * e.flat);
  // Refit (a skin's displaced surface): the corners' normals follow the vertices.
  auto verts = mesh_input(ball).vertices;
  for (auto& p : verts) p = Vec3f{p.x * 2.0f, p.y, p.z};  // an ellipsoid
  bvh->refit(verts);
  float s = 0;
  uint32_t slot = 0;
  REQUIRE(first_hit(bvh->view(), {0.3f, 0.2f, 3.0f}, {0, 0, -1}, 10.0f, s, slot));
  const Vec3f p = Vec3f{0.3f, 0.2f, 3.0f} + s * Vec3f{0, 0, -1};
  const Vec3f exact = normalized(Vec3f{p.x / 4.0f, p.y, p.z});  // grad of x^2/4 + y^2 + z^2
  CHECK(dot(shading_normal(bvh->view().tris[slot], p), exact) > std::cos(3.0 * M_PI / 180.0));
  // A box's faces stay flat: every corner is past the crease angle.
  const auto box = cpu_bvh(box_mesh({{-1, -0.5, -0.25}, {1, 0.5, 0.25}}));
  const NormalErrors b = normal_errors(box->view());
  CHECK(b.smooth_to_face < 1e-3);
}

TEST_CASE("a particle's path is stopped outside a closed mesh, whatever it grazes", "[mesh][cpu]") {
  const TriangleMesh m = sphere_mesh({0, 0, 0}, 0.1, 3);
  const auto bvh = cpu_bvh(m);
  Obstacles obs;
  obs.mesh[0] = bvh->view();
  obs.count = 1;
  obs.offset = 1e-4f;
  const auto box = box_mesh({{0.2, -0.05, -0.05}, {0.21, 0.05, 0.05}});  // a plate, faces on lattice planes
  const auto plate = cpu_bvh(box);
  obs.mesh[1] = plate->view();
  obs.count = 2;
  // The inscribed polyhedron lies within 0.1 of the centre and beyond 0.1 cos(edge angle).
  const float r_in = 0.0985f;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.15f, 0.15f);
  int stopped = 0;
  for (int k = 0; k < 20000; ++k) {
    Vec3f from{u(rng), u(rng), u(rng)};
    if (length(from) < 0.1001f) continue;  // start outside
    Vec3f to{u(rng), u(rng), u(rng)};
    stopped += stop_at_obstacles(obs, from, to, 0, 0).hit();
    CHECK(length(to) > r_in);
  }
  CHECK(stopped > 1000);
  // Resting exactly on the plate's face (as rounding can leave it) and moving in: stopped.
  Vec3f to{0.2005f, 0.01f, 0.0f};
  Vec3f n = stop_at_obstacles(obs, {0.2f, 0.01f, 0.0f}, to, 0, 0).normal;
  CHECK(n.x == Approx(-1.0f));
  CHECK(to.x < 0.2f);
  // Through the edge shared by the face's two triangles (its diagonal), and through a corner.
  to = {0.205f, 0.0f, 0.0f};
  stop_at_obstacles(obs, {0.19f, 0.0f, 0.0f}, to, 0, 0);
  CHECK(to.x < 0.2f);
  to = {0.205f, 0.05f, 0.05f};
  stop_at_obstacles(obs, {0.195f, 0.05f, 0.05f}, to, 0, 0);
  CHECK(to.x < 0.2f);
  // Along the face, outside: not stopped.
  to = {0.1999f, 0.04f, 0.0f};
  n = stop_at_obstacles(obs, {0.1999f, -0.04f, 0.0f}, to, 0, 0).normal;
  CHECK(to.y == 0.04f);
  CHECK(n.x == 0.0f);
}
