// Waves on an obstacle's skin (mesh/skin_map.h, sph/skin.h): the cube map
// against the mesh it comes from, the spherical embedding of a mesh that is
// not star-shaped, a single impulse's speed in every direction against the
// set wave speed (with and without the distortion correction), bounded
// free waves, and the guard against heights that grow. The skin driven by a
// pool's pressure is in test_obstacles.cpp.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "catch.h"
#include "helpers.h"
#include "mesh/mesh.h"
#include "mesh/skin_map.h"
#include "bench/skin.h"
#include "sph/skin.h"

using namespace sphray;

namespace {

bool inside(const Box& b, Vec3d p, double tol) {
  return p.x >= b.min.x - tol && p.x <= b.max.x + tol && p.y >= b.min.y - tol && p.y <= b.max.y + tol &&
         p.z >= b.min.z - tol && p.z <= b.max.z + tol;
}

// An elongated capsule-like mesh bent into a U: its middle lies outside the
// cone of its ends as seen from its centroid, so the central projection folds.
TriangleMesh bent_mesh() {
  const double bend = 2.0;  // rad either side: a U
  TriangleMesh m = sphere_mesh({0, 0, 0}, 1.0, 3, "bent");
  for (Vec3d& v : m.vertices) {
    const double x = 3.0 * v.x, y = 0.45 * v.y, z = 0.45 * v.z;  // a cigar along x
    const double a = x / 3.0 * bend;
    const double r = 1.0 + z;
    v = {r * std::sin(a), y, 1.0 - r * std::cos(a)};
  }
  return m;
}

}  // namespace

TEST_CASE("skin map: texels lie on the mesh, neighbours are near, every direction has one texel", "[mesh][skin]") {
  const TriangleMesh m = sphere_mesh({0.1, -0.2, 0.3}, 0.5, 3, "ball");
  const SkinMap s = make_skin_map(m, 16);
  REQUIRE(s.size() == size_t(6 * 16 * 16));
  CHECK(s.embedding.iterations == 0);  // a sphere is star-shaped about its centre
  // Every texel's point on the surface: within the icosphere's chord sag of the sphere.
  for (size_t i = 0; i < s.size(); ++i) {
    const double r = length(s.point[i] - Vec3d{0.1, -0.2, 0.3});
    CHECK(r <= 0.5 + 1e-9);
    CHECK(r >= 0.5 * 0.985);
    CHECK(dot(s.normal[i], s.point[i] - Vec3d{0.1, -0.2, 0.3}) > 0);
  }
  // Neighbours, across cube edges too, are within two texels' spacing and distinct.
  const double spacing = s.mean_spacing;
  CHECK(spacing == Approx(2 * M_PI * 0.5 / (4 * 16)).epsilon(0.25));
  for (size_t i = 0; i < s.size(); ++i)
    for (int q = 0; q < kSkinNeighbours; ++q) {
      if (s.neighbour[i][q] == i) continue;  // a cube corner's missing diagonal
      CHECK(s.distance[i][q] < 2.2 * spacing);
      CHECK(s.distance[i][q] > 0.3 * spacing);
    }
  // texel_of inverts the texel centres.
  for (int f = 0; f < 6; ++f)
    for (int j = 0; j < 16; ++j)
      for (int i = 0; i < 16; ++i) {
        const Vec3d d = cube_direction(f, -1.0 + (i + 0.5) / 8.0, -1.0 + (j + 0.5) / 8.0);
        CHECK(s.texel_of(d) == s.index(f, i, j));
      }
}

TEST_CASE("skin map: a mesh that is not star-shaped is relaxed onto the sphere without folds", "[mesh][skin]") {
  TriangleMesh m = bent_mesh();
  if (signed_volume(m) < 0) flip(m);  // the bend may mirror it
  check_mesh(m, 1e-12);
  // The central projection folds it ...
  std::vector<Vec3d> central(m.vertices.size());
  const SphereEmbedding e = embed_on_sphere(m);
  for (size_t i = 0; i < m.vertices.size(); ++i) central[i] = normalized(m.vertices[i] - e.centre);
  CHECK(folded_triangles(m, central) > 0);
  // ... the relaxed embedding does not, and every texel maps to the surface.
  CHECK(e.iterations > 0);
  CHECK(folded_triangles(m, e.u) == 0);
  const SkinMap s = make_skin_map(m, 48);
  const Box b = bounds(m);
  for (const Vec3d& p : s.point) CHECK(inside(b, p, 1e-9));
  // The texels reach nearly every part of it: all but a tenth of the
  // triangles have a texel within 5% of the mesh's size of their centroid
  // (a conformal map squeezes the ends of an elongated shape, where the
  // texels are sparser than the mean spacing).
  const double reach = 0.05 * length(b.max - b.min);
  size_t far = 0;
  for (const auto& t : m.triangles) {
    const Vec3d c = (m.vertices[t[0]] + m.vertices[t[1]] + m.vertices[t[2]]) * (1.0 / 3.0);
    double best = 1e30;
    for (const Vec3d& p : s.point) best = std::min(best, length(p - c));
    if (best > reach) ++far;
  }
  CHECK(far < m.size() / 10);
}

TEST_CASE("skin map: a mesh with no one-to-one spherical embedding is refused by name", "[mesh][skin]") {
  // A torus (genus 1): no one-to-one map onto the sphere exists.
  const TriangleMesh torus = test::torus_mesh("ring.obj");
  check_mesh(torus, 1e-12);
  try {
    embed_on_sphere(torus, 2000);
    FAIL("a torus was embedded on the sphere");
  } catch (const MeshError& e) {
    CHECK((test::has(e.what(), "ring.obj") && test::has(e.what(), "genus-0")));
  }
}

TEST_CASE("skin waves: an impulse spreads at the set speed, the same in every direction", "[mesh][skin]") {
  // Kira et al. correct the cube map's distortion by measuring the stencil's
  // distances on the real surface; in texture space the ring runs faster
  // over the small texels near the cube's corners than over the face
  // centres. The fitted stencil also follows the texel grid's skew there.
  const Vec3d src{0.3, 0.5, 0.8};
  const SkinImpulseSpeeds texture = skin_impulse_speeds(Backend::Cpu, 48, SkinStencil::Texture, src);
  const SkinImpulseSpeeds surface = skin_impulse_speeds(Backend::Cpu, 48, SkinStencil::Surface, src);
  const SkinImpulseSpeeds fitted = skin_impulse_speeds(Backend::Cpu, 48, SkinStencil::Fitted, src);
  auto spread = [](const SkinImpulseSpeeds& s) { return (s.max - s.min) / s.mean; };
  INFO("texture " << texture.mean << " [" << texture.min << ", " << texture.max << "]");
  INFO("surface " << surface.mean << " [" << surface.min << ", " << surface.max << "]");
  INFO("fitted " << fitted.mean << " [" << fitted.min << ", " << fitted.max << "]");
  CHECK(surface.mean == Approx(1.0).epsilon(0.03));
  CHECK(fitted.mean == Approx(1.0).epsilon(0.03));
  CHECK(spread(fitted) < 0.05);
  CHECK(spread(surface) < 0.12);
  CHECK(spread(texture) > 0.3);
}

TEST_CASE("skin waves: free waves stay bounded for many crossings of the sphere", "[mesh][skin]") {
  // The fitted stencil's weights may be negative; its steps must still not
  // let the heights grow. A bump, no damping, 20 s (about six crossings).
  for (const SkinStencil st : {SkinStencil::Surface, SkinStencil::Fitted}) {
    SkinInput in;
    in.mesh = sphere_mesh({0, 0, 0}, 1.0, 4, "sphere");
    in.params.resolution = 24;
    in.params.damping = 0.0f;
    in.params.frequency = 1e-6f;
    in.params.stencil = st;
    std::vector<SkinGeometry> geo;
    geo.push_back(make_skin_geometry(in));
    std::vector<float> h(geo[0].map.size());
    for (size_t i = 0; i < h.size(); ++i) h[i] = float(std::exp(-8.0 * length2(normalized(geo[0].map.point[i]) - Vec3d{0, 0, 1})));
    auto skins = make_cpu_skin_set(std::move(geo), SphParams{});
    skins->set_heights(0, h);
    double peak = 0;
    for (int k = 0; k < 2000; ++k) {
      skins->advance(ParticleView{}, nullptr, k * 0.01, 0.01);
      if (k % 100 == 99)
        for (const float v : skins->heights(0)) peak = std::max(peak, double(std::abs(v)));
    }
    INFO(stencil_name(st));
    CHECK(std::isfinite(peak));
    CHECK(peak < 1.2);
  }
}
TEST_CASE("skin waves on the bunny: free waves stay bounded; a skin blown apart stops the run", "[mesh][skin]") {
  // The bunny is not star-shaped (its map needs the flow) and its conformal
  // map squeezes and skews texels (ears, feet).
  SkinInput in;
  in.mesh = placed(read_obj(test::source_path("scenes/meshes/bunny.obj")), Placement{{0.12, 0.12, 0.12}, {90, 0, 0}, {0, 0, 0}});
  in.params.resolution = 48;
  in.params.wave_speed = 0.6f;
  in.params.damping = 0.0f;
  in.params.frequency = 1e-6f;
  std::vector<SkinGeometry> geo;
  geo.push_back(make_skin_geometry(in));
  CHECK(geo[0].map.embedding.iterations > 0);
  CHECK(*std::min_element(geo[0].coef.begin(), geo[0].coef.end()) >= 0.0f);
  // A bump on its back, 3 s of free waves (several crossings of the bunny).
  std::vector<float> h(geo[0].map.size());
  const Vec3d top = geo[0].map.point[geo[0].map.texel_of({0.2, 0.3, 1.0})];
  for (size_t i = 0; i < h.size(); ++i) h[i] = float(1e-3 * std::exp(-length2(geo[0].map.point[i] - top) / (2 * 0.01 * 0.01)));
  const double size = geo[0].size;
  auto skins = make_cpu_skin_set(std::move(geo), SphParams{});
  skins->set_heights(0, h);
  double peak = 0;
  for (int k = 0; k < 3000; ++k) {
    skins->advance(ParticleView{}, nullptr, k * 1e-3, 1e-3);
    if (k % 100 == 99)
      for (const float v : skins->heights(0)) peak = std::max(peak, double(std::abs(v)));
  }
  CHECK(std::isfinite(peak));
  CHECK(peak < 1.2e-3);
  // Heights beyond a quarter of the mesh's size: the guard stops the run within kSkinCheckEvery advances.
  skins->set_heights(0, std::vector<float>(h.size(), float(0.3 * size)));
  try {
    for (int k = 0; k < kSkinCheckEvery; ++k) skins->advance(ParticleView{}, nullptr, 3.0, 1e-3);
    FAIL("a skin displaced by 0.3 of its size ran on");
  } catch (const SimulationError& e) {
    CHECK((test::has(e.what(), "obstacles.0.skin") && test::has(e.what(), "grew without bound")));
  }
}
