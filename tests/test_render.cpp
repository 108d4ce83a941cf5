// The raycaster (render/raycast.h) on the CPU backend against analytic
// answers computed in double: the hit distance and normal on a sphere field,
// Snell refraction through a sphere, total internal reflection at a flat
// surface, weights that never sum above 1; the empty-space skip against no
// skip; images, PNG and PSNR.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <vector>

#include "catch.h"
#include "helpers.h"
#include "host_particles.h"
#include "still_pool.h"
#include "field/field.h"
#include "mesh/bvh.h"
#include "mesh/mesh.h"
#include "pipeline/setup.h"
#include "render/render.h"

using namespace sphray;

namespace {

constexpr int N = 48;          // analytic volumes: N^3 voxels
constexpr double kIso = 10.0;  // f = iso + (signed distance inside), clamped at 0

struct AnalyticVolume {
  std::vector<float> f;
  explicit AnalyticVolume(double (*inside_distance)(double, double, double)) : f(size_t(N) * N * N) {
    for (int k = 0; k < N; ++k)
      for (int j = 0; j < N; ++j)
        for (int i = 0; i < N; ++i)
          f[(size_t(k) * N + j) * N + i] = float(std::max(0.0, kIso + inside_distance(i + 0.5, j + 0.5, k + 0.5)));
  }
};

constexpr double kC = 24.0, kRho = 12.0;  // sphere centre (each axis) and radius [voxels]
double sphere(double x, double y, double z) {
  return kRho - std::sqrt((x - kC) * (x - kC) + (y - kC) * (y - kC) + (z - kC) * (z - kC));
}
// Two spheres of radius 8 side by side along x, 4 voxels apart.
constexpr double kR2 = 8.0, kXa = 14.0, kXb = 34.0;
double two_spheres(double x, double y, double z) {
  auto in = [&](double cx) { return kR2 - std::sqrt((x - cx) * (x - cx) + (y - kC) * (y - kC) + (z - kC) * (z - kC)); };
  return std::max(in(kXa), in(kXb));
}
constexpr double kZ0 = 30.0;  // liquid below this plane
double half_space(double, double, double z) { return kZ0 - z; }

TraceSettings settings(int interfaces, double absorption = 0.0) {
  const float a = float(absorption);
  return TraceSettings{float(kIso), 0.5f, interfaces, 1.33f, Rgb{a, a, a}, 3};
}
// Both branches of every interface, to `interfaces` along each path, nothing cut.
TraceSettings all_branches(int interfaces) {
  TraceSettings ts = settings(interfaces);
  ts.reflections = true;
  ts.budget = 255;
  ts.min_weight = 0;
  return ts;
}

Tracer<TrilinearField> make_tracer(const AnalyticVolume& v, const TraceSettings& ts) {
  Environment env{};
  env.tank_lo = {0, 0, 0};
  env.tank_hi = {float(N), float(N), float(N)};
  env.tile = 4;
  env.sun = normalized(Vec3f{0.3f, 0.2f, 0.9f});
  return Tracer<TrilinearField>{TrilinearField{v.f.data(), N, N, N}, Occupancy{nullptr, 0, 0, 0, 1},
                                Vec3f{float(N), float(N), float(N)}, env, ts};
}

struct Event {
  Vec3f p, n, d;
  bool tir;
  float F;
};
// Records what one trace did.
struct Watch {
  std::vector<Event>* events;
  std::vector<Rgb>* weights;
  void segment(Vec3f, Vec3f, bool) const {}
  void interface(Vec3f p, Vec3f n, Vec3f d, bool tir, float F) const { events->push_back({p, n, d, tir, F}); }
  void contribution(Rgb w) const { weights->push_back(w); }
};

Vec3d dbl(Vec3f v) { return {v.x, v.y, v.z}; }
Vec3f unit_f(Vec3f v) { return v * (1.0f / std::sqrt(dot(v, v))); }
double angle(Vec3d a, Vec3d b) { return std::acos(std::clamp(dot(normalized(a), normalized(b)), -1.0, 1.0)); }

// Double-precision Snell (n facing against d).
bool refract_d(Vec3d d, Vec3d n, double eta, Vec3d& out) {
  const double ci = -dot(n, d), k = 1 - eta * eta * (1 - ci * ci);
  if (k < 0) return false;
  out = d * eta + n * (eta * ci - std::sqrt(k));
  return true;
}
// Ray against the analytic sphere: nearest t > eps (inside or outside).
double hit_sphere(Vec3d o, Vec3d d, double eps = 1e-6) {
  const Vec3d oc = o - Vec3d{kC, kC, kC};
  const double b = dot(oc, d), c = dot(oc, oc) - kRho * kRho, disc = b * b - c;
  if (disc < 0) return -1;
  const double t0 = -b - std::sqrt(disc), t1 = -b + std::sqrt(disc);
  return t0 > eps ? t0 : (t1 > eps ? t1 : -1);
}
double schlick_d(double n1, double n2, double c) {
  const double r0 = std::pow((n1 - n2) / (n1 + n2), 2);
  return r0 + (1 - r0) * std::pow(1 - c, 5);
}

template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

// The trilinear interpolant between voxel centres at u (voxel units) in
// double, the one the tracer samples; at(i, j, k) gives a voxel (0 outside).
template <class At>
double trilinear_at(const At& at, Vec3d u) {
  const double x = u.x - 0.5, y = u.y - 0.5, z = u.z - 0.5;
  const int i = int(std::floor(x)), j = int(std::floor(y)), k = int(std::floor(z));
  const double a = x - i, b = y - j, c = z - k;
  double s = 0;
  for (int dk = 0; dk < 2; ++dk)
    for (int dj = 0; dj < 2; ++dj)
      for (int di = 0; di < 2; ++di)
        s += at(i + di, j + dj, k + dk) * (di ? a : 1 - a) * (dj ? b : 1 - b) * (dk ? c : 1 - c);
  return s;
}
// f of an analytic volume at u.
double trilinear_d(const AnalyticVolume& v, Vec3d u) {
  return trilinear_at(
      [&](int i, int j, int k) -> double {
        if (i < 0 || j < 0 || k < 0 || i >= N || j >= N || k >= N) return 0.0;
        return v.f[(size_t(k) * N + j) * N + i];
      },
      u);
}

// A realistic field: random clusters of particles through the naive builder.
struct Clusters {
  Scene s = parse_scene(R"({"tank": {"min": [0,0,0], "max": [0.4,0.2,0.3]},
    "fluid": [{"min": [0,0,0], "max": [0.12,0.2,0.2]}], "sph": {"spacing": 0.01}, "run": {"end_time": 1}})",
                        "render.json");
  FieldSetup fs = make_field_setup(resolve_scene(s));
  std::vector<float> field;
  Environment env = make_environment(s.tank, fs.geom, make_camera(s.tank, s.render));
  Vec3f box{float(fs.geom.nx), float(fs.geom.ny), float(fs.geom.nz)};

  Clusters() {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0, 1);
    std::normal_distribution<float> g(0, 0.02f);
    std::vector<Vec3f> pts;
    for (int c = 0; c < 12; ++c) {
      const Vec3f centre{0.05f + 0.3f * u(rng), 0.03f + 0.14f * u(rng), 0.03f + 0.2f * u(rng)};
      for (int k = 0; k < 250; ++k) pts.push_back({centre.x + g(rng), centre.y + g(rng), centre.z + g(rng)});
    }
    for (auto& p : pts) {
      p.x = std::clamp(p.x, 0.001f, 0.399f);
      p.y = std::clamp(p.y, 0.001f, 0.199f);
      p.z = std::clamp(p.z, 0.001f, 0.299f);
    }
    const HostParticleSet ps(measure_scene(s).grid, pts);
    auto builder = make_cpu_field_builder(fs, FieldKind::Naive);
    builder->build(ps.view());
    field = builder->download();
  }
  template <int Pending = 16>
  Tracer<TrilinearField, Pending> tracer(const TraceSettings& ts) const {
    return {TrilinearField{field.data(), fs.geom.nx, fs.geom.ny, fs.geom.nz}, Occupancy{nullptr, 0, 0, 0, 1}, box, env,
            ts};
  }
  // A ray from in front of the tank toward a random point of the volume.
  template <class Rng>
  void random_ray(Rng& rng, Vec3f& o, Vec3f& d) const {
    std::uniform_real_distribution<float> u(0, 1);
    o = Vec3f{box.x * u(rng), -10.0f, box.z * (0.2f + 0.8f * u(rng))};
    const Vec3f target{box.x * u(rng), box.y * u(rng), box.z * u(rng)};
    d = normalized(target - o);
  }
};

}  // namespace

TEST_CASE("ray hits a sphere field at the analytic distance with the analytic normal", "[render]") {
  const AnalyticVolume vol(sphere);
  const auto tracer = make_tracer(vol, settings(1));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> off(-0.9 * kRho, 0.9 * kRho);
  double worst_root = 0, worst_radius = 0, worst_n = 0;
  int hits = 0;
  for (int r = 0; r < 200; ++r) {
    // from outside the box toward a random point of the sphere's silhouette disc
    const Vec3d o{-20.0, kC + off(rng), kC + off(rng) * 0.5};
    const Vec3d aim{kC, kC + off(rng) * 0.6, kC + off(rng) * 0.6};
    const Vec3d d = normalized(aim - o);
    const double t_ref = hit_sphere(o, d);
    if (t_ref < 0) continue;
    ++hits;
    std::vector<Event> ev;
    std::vector<Rgb> w;
    tracer.trace(Vec3f{float(o.x), float(o.y), float(o.z)}, Vec3f{float(d.x), float(d.y), float(d.z)},
                 Watch{&ev, &w});
    REQUIRE(ev.size() == 1);
    const double t = dot(dbl(ev[0].p) - o, d);
    // (1) the marcher: the root of the sampled (trilinear) field along the ray, by bisection in double
    double lo = t_ref - 1.0, hi = t_ref + 1.0;
    REQUIRE(trilinear_d(vol, o + d * lo) < kIso);
    REQUIRE(trilinear_d(vol, o + d * hi) >= kIso);
    for (int it = 0; it < 60; ++it) (trilinear_d(vol, o + d * (0.5 * (lo + hi))) < kIso ? lo : hi) = 0.5 * (lo + hi);
    worst_root = std::max(worst_root, std::abs(t - 0.5 * (lo + hi)));
    // (2) the surface: trilinear interpolation of a distance field deviates from the sphere by at most
    // sum_i h_i^2 |d2f/dxi2| / 8 = 3 / (8 rho) = 0.031 voxels along the normal
    worst_radius = std::max(worst_radius, std::abs(length(dbl(ev[0].p) - Vec3d{kC, kC, kC}) - kRho));
    // the recorded normal faces the incoming ray: outward at an entry
    const Vec3d hit = o + d * t_ref;
    worst_n = std::max(worst_n, angle(dbl(ev[0].n), hit - Vec3d{kC, kC, kC}));
  }
  INFO(hits << " hits: worst distance to the field's root " << worst_root << ", worst radial error " << worst_radius
            << " voxels, worst normal error " << worst_n << " rad");
  CHECK(hits > 100);
  CHECK(worst_root < 2e-3);
  CHECK(worst_radius < 0.031);
  CHECK(worst_n < 0.01);
}

// A sphere centred on the tank's glass wall x = 8: its part at x < 8 lies in
// the volume's margin, outside the tank, where liquid cannot be.
double sphere_on_glass(double x, double y, double z) {
  return kRho - std::sqrt((x - 8.0) * (x - 8.0) + (y - kC) * (y - kC) + (z - kC) * (z - kC));
}

TEST_CASE("the liquid is confined to the tank: glass is the interface, the margin holds none", "[render]") {
  const AnalyticVolume vol(sphere_on_glass);
  auto tracer = make_tracer(vol, settings(4));
  tracer.env.tank_lo.x = 8.0f;  // the -x wall at x = 8, glass
  tracer.env.glass = 1;
  std::vector<Event> ev;
  std::vector<Rgb> w;
  // (1) Through the glass where the liquid touches it: the first interface is
  // on the glass plane with the glass's normal (the field would put it at
  // x = 0, the volume box, with the box's normal, or on the spilled sphere).
  for (const double y : {kC - 6.0, kC, kC + 3.0}) {
    ev.clear();
    const Vec3d d = normalized(Vec3d{1.0, 0.05, -0.1});
    tracer.trace(Vec3f{-10.0f, float(y), float(kC)}, Vec3f{float(d.x), float(d.y), float(d.z)}, Watch{&ev, &w});
    REQUIRE(!ev.empty());
    CHECK(std::abs(ev[0].p.x - 8.0f) < 1e-3f);
    CHECK(ev[0].n.x == -1.0f);
    CHECK(ev[0].n.y == 0.0f);
    CHECK(ev[0].n.z == 0.0f);
  }
  // (2) A ray through the sphere's part in the margin only (x = 4, outside the
  // tank) meets no liquid.
  ev.clear();
  tracer.trace(Vec3f{4.0f, -10.0f, float(kC)}, Vec3f{0.0f, 1.0f, 0.0f}, Watch{&ev, &w});
  CHECK(ev.empty());
  // (3) From inside the liquid toward the glass: an interface on the glass
  // plane with the glass's normal (here at 69 degrees: totally reflected).
  ev.clear();
  tracer.trace(Vec3f{30.0f, float(kC), float(kC) + 40.0f}, unit_f(Vec3f{-0.5f, 0.0f, -1.0f}), Watch{&ev, &w});
  bool at_glass = false;
  for (const Event& e : ev)  // (the watch sees the normal facing the ray)
    at_glass = at_glass || (std::abs(e.p.x - 8.0f) < 1e-3f && std::abs(e.n.x) == 1.0f && e.tir);
  CHECK(at_glass);
}

TEST_CASE("a ray that starts across the surface finds its crossing within its segment", "[render]") {
  // Branches start on the surface, within the hit's accuracy of it: a start
  // already across (outside state, field above iso, or the reverse) must give
  // a crossing in [0, t_max], never one extrapolated off the segment.
  const AnalyticVolume vol(sphere);
  const auto tracer = make_tracer(vol, settings(4));
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1, 1);
  int checked = 0;
  for (int r = 0; r < 2000; ++r) {
    const Vec3f n = normalized(Vec3f{u(rng), u(rng), u(rng)});
    const float depth = 0.3f * u(rng);  // voxels inside (+) or outside (-) the sphere's surface
    const Vec3f p = Vec3f{float(kC), float(kC), float(kC)} + n * float(kRho - depth);
    const Vec3f d = normalized(Vec3f{u(rng), u(rng), u(rng)});
    for (bool inside : {false, true}) {
      const float t_max = 20.0f;
      const float th = tracer.find_crossing(p, d, t_max, inside);
      INFO("depth " << depth << ", inside " << inside << ": crossing at " << th);
      CHECK((th == -1.0f || (th >= 0.0f && th <= t_max)));
      ++checked;
    }
  }
  CHECK(checked == 4000);
}

TEST_CASE("a ray refracts through a sphere as Snell's law says", "[render]") {
  const AnalyticVolume vol(sphere);
  const auto tracer = make_tracer(vol, settings(2));
  const double eta = 1.33;
  for (double b : {0.0, 0.3, 0.6, 0.85}) {
    const Vec3d o{-20.0, kC + b * kRho * 0.8, kC + b * kRho * 0.6}, d{1, 0, 0};
    // analytic path in double
    const double t1 = hit_sphere(o, d);
    const Vec3d p1 = o + d * t1, n1 = normalized(p1 - Vec3d{kC, kC, kC});
    Vec3d r1;
    REQUIRE(refract_d(d, n1, 1.0 / eta, r1));
    const double t2 = hit_sphere(p1, r1, 1e-6);
    const Vec3d p2 = p1 + r1 * t2, n2 = normalized(Vec3d{kC, kC, kC} - p2);  // inward: faces the ray inside
    Vec3d r2;
    REQUIRE(refract_d(r1, n2, eta, r2));
    // total deviation 2 (theta_i - theta_t) around the incidence plane
    const double ti = std::asin(b), tt = std::asin(b / eta);
    CHECK(angle(d, r2) == Approx(2 * (ti - tt)).margin(1e-9));

    std::vector<Event> ev;
    std::vector<Rgb> w;
    tracer.trace(Vec3f{float(o.x), float(o.y), float(o.z)}, Vec3f{1, 0, 0}, Watch{&ev, &w});
    INFO("impact parameter " << b);
    REQUIRE(ev.size() == 2);
    CHECK(!ev[0].tir);
    CHECK(!ev[1].tir);
    // along the ray the surface error (0.031 voxels along the normal, see above) grows as 1 / cos
    const double cos_i = std::cos(ti), cos_t = std::cos(tt);
    CHECK(length(dbl(ev[0].p) - p1) < 0.031 / cos_i + 1e-3);
    CHECK(angle(dbl(ev[0].d), r1) < 0.01);
    CHECK(length(dbl(ev[1].p) - p2) < 2 * 0.031 / cos_t + 1e-3);
    CHECK(angle(dbl(ev[1].d), r2) < 0.02);
    // Fresnel weights: Schlick at the analytic angles (entering: cos_i; leaving: the cosine outside)
    CHECK(ev[0].F == Approx(schlick_d(1, eta, std::cos(ti))).margin(2e-3));
    CHECK(ev[1].F == Approx(schlick_d(eta, 1, std::cos(ti))).margin(2e-3));
  }
}

TEST_CASE("total internal reflection beyond the critical angle, refraction below it", "[render]") {
  const AnalyticVolume vol(half_space);
  const auto tracer = make_tracer(vol, settings(1));
  const double critical = std::asin(1 / 1.33) * 180 / M_PI;  // 48.75 degrees
  for (double deg : {20.0, 45.0, critical - 1.0, critical + 1.0, 60.0, 80.0}) {
    const double a = deg * M_PI / 180;
    const Vec3d d{std::sin(a), 0, std::cos(a)};
    const Vec3d o{4.0, kC, kZ0 - 6.0};  // in the liquid, under the surface
    std::vector<Event> ev;
    std::vector<Rgb> w;
    tracer.trace(Vec3f{float(o.x), float(o.y), float(o.z)}, Vec3f{float(d.x), float(d.y), float(d.z)},
                 Watch{&ev, &w});
    INFO(deg << " degrees from the normal");
    REQUIRE(ev.size() == 1);
    const Vec3d hit = o + d * (6.0 / std::cos(a));
    CHECK(length(dbl(ev[0].p) - hit) < 0.02);
    const bool tir = deg > critical;
    CHECK(ev[0].tir == tir);
    if (tir) {
      CHECK(angle(dbl(ev[0].d), Vec3d{d.x, 0, -d.z}) < 1e-3);
      CHECK(ev[0].F == 1.0f);
    } else {
      Vec3d r;
      REQUIRE(refract_d(d, Vec3d{0, 0, -1}, 1.33, r));
      CHECK(std::sin(angle(dbl(ev[0].d), Vec3d{0, 0, 1})) == Approx(1.33 * std::sin(a)).margin(2e-3));
      CHECK(angle(dbl(ev[0].d), r) < 2e-3);
    }
  }
}

TEST_CASE("with reflections every branch of a sphere is traced: the internal chain in double", "[render]") {
  // Entering a sphere, a ray splits into the outer reflection and a chain of
  // internal reflections, each leaving a refracted part at the same angle.
  // With every branch traced to 8 interfaces: 1 entry + 7 internal hits, each
  // a chord of central angle pi - 2 theta_t on from the last, and the pixel's
  // weights are F0, T0 (1 - F1) F1^j (j = 0..6) and T0 F1^7.
  const AnalyticVolume vol(sphere);
  const auto tracer = make_tracer(vol, all_branches(8));
  const double eta = 1.33;
  for (double b : {0.3, 0.6, 0.85}) {
    const Vec3d o{-20.0, kC + b * kRho * 0.8, kC + b * kRho * 0.6};
    const double ti = std::asin(b), tt = std::asin(b / eta);
    const double F0 = schlick_d(1, eta, std::cos(ti)), F1 = schlick_d(eta, 1, std::cos(ti)), T0 = 1 - F0;
    std::vector<Event> ev;
    std::vector<Rgb> w;
    tracer.trace(Vec3f{float(o.x), float(o.y), float(o.z)}, Vec3f{1, 0, 0}, Watch{&ev, &w});
    INFO("impact parameter " << b);
    REQUIRE(ev.size() == 8);
    CHECK(ev[0].F == Approx(F0).margin(2e-3));
    const Vec3d c{kC, kC, kC};
    for (size_t e = 0; e < ev.size(); ++e) {
      INFO("interface " << e);
      CHECK(!ev[e].tir);
      CHECK(std::abs(length(dbl(ev[e].p) - c) - kRho) < 0.05);
      if (e == 0) continue;
      CHECK(ev[e].F == Approx(F1).margin(3e-3));
      CHECK(angle(dbl(ev[e].p) - c, dbl(ev[e - 1].p) - c) == Approx(M_PI - 2 * tt).margin(0.01 * double(e)));
    }
    std::vector<double> expect{F0}, got;
    for (int j = 0; j < 7; ++j) expect.push_back(T0 * (1 - F1) * std::pow(F1, j));
    expect.push_back(T0 * std::pow(F1, 7));
    for (const Rgb& x : w) {
      CHECK(x.r == x.g);
      if (x.r > 0) got.push_back(x.r);  // (segments inside add a zero share: no absorption here)
    }
    std::sort(expect.begin(), expect.end());
    std::sort(got.begin(), got.end());
    REQUIRE(got.size() == expect.size());
    for (size_t k = 0; k < got.size(); ++k) CHECK(got[k] == Approx(expect[k]).epsilon(0.02).margin(1e-9));
    // without reflections the chain stops at the first exit
    ev.clear();
    w.clear();
    make_tracer(vol, settings(8)).trace(Vec3f{float(o.x), float(o.y), float(o.z)}, Vec3f{1, 0, 0}, Watch{&ev, &w});
    CHECK(ev.size() == 2);
  }
}

TEST_CASE("the reflected branch shows more liquid: one sphere seen in another", "[render]") {
  // A ray along +y meets sphere A at 45 degrees: its reflection runs along +x
  // into sphere B, where it enters at the analytic point and angle.
  const AnalyticVolume vol(two_spheres);
  const double s45 = std::sqrt(0.5);
  const Vec3d o{kXa + kR2 * s45, -20.0, kC};
  const Vec3d at_b{kXb - kR2 * s45, kC - kR2 * s45, kC};  // where the reflected ray enters B
  auto meets_b = [&](const std::vector<Event>& ev, float& F) {
    for (const Event& e : ev)
      if (length(dbl(e.p) - at_b) < 0.15) {
        F = e.F;
        return true;
      }
    return false;
  };
  std::vector<Event> ev;
  std::vector<Rgb> w;
  float F = 0;
  make_tracer(vol, settings(4)).trace(Vec3f{float(o.x), float(o.y), float(o.z)}, Vec3f{0, 1, 0}, Watch{&ev, &w});
  CHECK_FALSE(meets_b(ev, F));
  for (int budget : {1, 16}) {
    TraceSettings ts = settings(4);
    ts.reflections = true;
    ts.budget = budget;
    ev.clear();
    w.clear();
    const Rgb colour =
        make_tracer(vol, ts).trace(Vec3f{float(o.x), float(o.y), float(o.z)}, Vec3f{0, 1, 0}, Watch{&ev, &w});
    INFO("budget " << budget << ", " << ev.size() << " interfaces");
    CHECK(int(ev.size()) <= 4 + budget);
    CHECK(std::isfinite(colour.r + colour.g + colour.b));
    // the refracted branch (weight 1 - F) goes first, through A; then the
    // strongest waiting branch: the reflection (F) before the internal one
    // ((1 - F) F'), into B with its first interface
    REQUIRE(meets_b(ev, F));
    CHECK(F == Approx(schlick_d(1, 1.33, s45)).margin(3e-3));
  }
}

TEST_CASE("the weights of one pixel sum to 1: absorbed shares, reflections and budgets", "[render]") {
  // What the liquid absorbs is replaced by its tint, and every branch not
  // followed takes the environment: the shares of a pixel add up to 1.
  const Clusters cl;
  const FieldSetup& fs = cl.fs;
  std::mt19937 rng(5);
  struct Mode {
    bool reflections;
    int budget;
  };
  for (double absorption : {0.0, 0.05}) {
    for (int interfaces : {1, 4, 8}) {
      for (Mode m : {Mode{false, 0}, Mode{true, 1}, Mode{true, 3}, Mode{true, 16}}) {
        TraceSettings ts{fs.shape.iso, 0.5f, interfaces, 1.33f, Rgb{float(absorption), float(absorption * 0.5), 0.0f}, 3};
        ts.reflections = m.reflections;
        ts.budget = m.budget;
        ts.tint = Rgb{0.1f, 0.3f, 0.4f};
        const auto tracer = cl.tracer(ts);
        double worst = 0;
        int with_interfaces = 0;
        for (int r = 0; r < 400; ++r) {
          Vec3f o, d;
          cl.random_ray(rng, o, d);
          std::vector<Event> ev;
          std::vector<Rgb> w;
          tracer.trace(o, d, Watch{&ev, &w});
          with_interfaces += !ev.empty();
          CHECK(int(ev.size()) <= interfaces + (m.reflections ? m.budget : 0));
          Rgb sum{0, 0, 0};
          for (const Rgb& c : w) {
            CHECK(std::min({c.r, c.g, c.b}) >= 0.0f);
            sum = sum + c;
          }
          for (float c : {sum.r, sum.g, sum.b}) worst = std::max(worst, std::abs(double(c) - 1.0));
        }
        INFO("absorption " << absorption << ", " << interfaces << " interfaces, reflections " << m.reflections
                           << " budget " << m.budget << ": " << with_interfaces << " of 400 rays met the liquid");
        CHECK(with_interfaces > 100);
        CHECK(worst <= 1e-5);
      }
    }
  }
}

TEST_CASE("reflections: the budget converges to every branch; 16 slots hold every branch at budgets up to 16", "[render]") {
  // Every branch to 8 interfaces (at most 255 per pixel) with the renderer's
  // 16 waiting slots against 256 slots (never full). At the default budget
  // (8) and at 16 the slots never fill: the same pixel. On the whole tree
  // they may (when full, the weakest branch takes the environment): here 2
  // of 600 rays, of 98 and 120 interfaces, change by 1.3 levels of 255 and
  // less. And the error against the whole tree falls as the budget grows.
  const Clusters cl;
  TraceSettings full{cl.fs.shape.iso, 0.5f, 8, 1.33f, Rgb{0.02f, 0.01f, 0.005f}, 3};
  full.reflections = true;
  full.budget = 255;
  full.tint = Rgb{0.1f, 0.3f, 0.4f};
  const auto reference = cl.tracer<256>(full);
  const auto renderer_slots = cl.tracer(full);
  auto difference = [](Rgb a, Rgb b) {
    return std::max({double(std::abs(a.r - b.r)), double(std::abs(a.g - b.g)), double(std::abs(a.b - b.b))});
  };
  std::mt19937 rng(11);
  std::vector<Vec3f> os, ds;
  std::vector<Rgb> ref;
  double slots_error = 0;
  int slots_differ = 0;
  for (int r = 0; r < 600; ++r) {
    Vec3f o, d;
    cl.random_ray(rng, o, d);
    os.push_back(o);
    ds.push_back(d);
    ref.push_back(reference.trace(o, d));
    const double e = difference(renderer_slots.trace(o, d), ref.back());
    slots_error = std::max(slots_error, e);
    slots_differ += e >= 1e-4;
  }
  INFO("whole tree: " << slots_differ << " of 600 pixels differ with 16 slots, by at most " << slots_error);
  CHECK(slots_differ <= 6);
  CHECK(slots_error < 2.0 / 255);
  for (int budget : {8, 16}) {
    TraceSettings ts = full;
    ts.budget = budget;
    const auto wide = cl.tracer<256>(ts);
    const auto slots = cl.tracer(ts);
    double worst = 0;
    for (size_t r = 0; r < os.size(); ++r) worst = std::max(worst, difference(slots.trace(os[r], ds[r]), wide.trace(os[r], ds[r])));
    INFO("budget " << budget << ": 16 slots against 256, largest difference " << worst);
    CHECK(worst < 1e-4);
  }
  std::vector<double> errors;
  for (int budget : {0, 2, 4, 8, 16, 64}) {
    TraceSettings ts = full;
    ts.reflections = budget > 0;
    ts.budget = budget > 0 ? budget : 1;
    ts.min_weight = budget > 0 ? 1.0f / 256 : 0.0f;
    const auto tracer = cl.tracer(ts);
    double sum = 0;
    for (size_t r = 0; r < os.size(); ++r) {
      const Rgb c = tracer.trace(os[r], ds[r]);
      sum += std::abs(c.r - ref[r].r) + std::abs(c.g - ref[r].g) + std::abs(c.b - ref[r].b);
    }
    errors.push_back(sum / double(3 * os.size()));
    INFO("budget " << budget << ": mean error " << errors.back());
    CHECK(std::isfinite(errors.back()));
    if (errors.size() > 1) CHECK(errors.back() <= errors[errors.size() - 2] + 1e-6);
  }
  // (measured: 0.0060 without reflections, 0.0025, 0.0014, 0.0008, 0.0003, 0.0001 at budgets 2, 4, 8, 16, 64;
  // the floor is min_weight's)
  CHECK(errors.back() < 0.05 * errors.front());
}

TEST_CASE("brick skipping is exact and leaves the image unchanged", "[render]") {
  const Scene s = load_scene(test::source_path("scenes/dam_break.json"),
                             {"sph.spacing=0.04", "render.width=160", "render.height=90"});
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
  auto solver = make_cpu_solver(in);
  for (int k = 0; k < 60; ++k) solver->step(1.0);  // the column starts to fall: a surface with a front
  for (int refine : {0, 2}) {
    const Scene sr = load_scene(test::source_path("scenes/dam_break.json"),
                                {"sph.spacing=0.04", "render.width=160", "render.height=90",
                                 "field.refine=" + std::to_string(refine)});
    const FieldSetup fs = make_field_setup(resolve_scene(sr));
    auto builder = make_cpu_field_builder(fs, FieldKind::Naive);
    const ParticleView pv = solver->view();
    builder->build(pv);
    const std::vector<float> f = builder->download();
    // the guarantee: in a brick (an SPH cell of the volume, as the renderer's)
    // called air (liquid) the trilinear field, sampled in double on a 9^3
    // lattice over the brick and its faces, is below (at or above) iso everywhere
    const VolumeGeom& g = fs.geom;
    const int B = 1 << g.refine, cx = (g.nx + B - 1) / B, cy = (g.ny + B - 1) / B, cz = (g.nz + B - 1) / B;
    std::vector<uint8_t> occ(size_t(cx) * cy * cz);
    for (uint32_t c = 0; c < occ.size(); ++c) BuildOccupancy{f.data(), g.nx, g.ny, g.nz, B, fs.shape.iso, occ.data()}(c);
    auto voxel = [&](int i, int j, int k) -> double {
      if (i < 0 || j < 0 || k < 0 || i >= g.nx || j >= g.ny || k >= g.nz) return 0.0;
      return f[g.index(i, j, k)];
    };
    size_t air = 0, liquid = 0, violations = 0;
    for (int bk = 0; bk < cz; ++bk)
      for (int bj = 0; bj < cy; ++bj)
        for (int bi = 0; bi < cx; ++bi) {
          const uint8_t o = occ[(size_t(bk) * cy + bj) * cx + bi];
          air += o == Occupancy::kAir;
          liquid += o == Occupancy::kLiquid;
          if (o == Occupancy::kMayCross) continue;
          for (int sk = 0; sk <= 8; ++sk)
            for (int sj = 0; sj <= 8; ++sj)
              for (int si = 0; si <= 8; ++si) {
                const double v = trilinear_at(voxel, Vec3d{B * (bi + si / 8.0), B * (bj + sj / 8.0), B * (bk + sk / 8.0)});
                violations += o == Occupancy::kAir ? !(v < fs.shape.iso) : !(v >= fs.shape.iso);
              }
        }
    INFO("refine " << refine << ": " << air << " air and " << liquid << " liquid bricks of " << occ.size());
    CHECK(violations == 0);
    CHECK(air > occ.size() / 4);  // the skip has something to skip
    if (refine == 2) CHECK(liquid > 0);

    RenderSettings rs = sr.render;
    const Camera cam = make_camera(sr.tank, rs);
    const Environment env = make_environment(sr.tank, fs.geom, cam);
    auto renderer = make_cpu_renderer();
    rs.skip_empty = false;
    renderer->render(builder->data(), fs, cam, env, rs);
    const Image plain = renderer->download();
    rs.skip_empty = true;
    renderer->render(builder->data(), fs, cam, env, rs);
    const Image skipped = renderer->download();
    const size_t differ = pixels_differing(plain, skipped, 2);
    INFO("PSNR " << psnr(plain, skipped) << " dB, " << differ << " pixels differ by more than 2 levels");
    CHECK(psnr(plain, skipped) > 45.0);
    CHECK(differ < plain.rgba.size() / 500);
    // the liquid is in the picture: an empty field renders differently
    const std::vector<float> zero(f.size(), 0.0f);
    renderer->render(zero.data(), fs, cam, env, rs);
    CHECK(psnr(renderer->download(), skipped) < 30.0);
  }
}

TEST_CASE("PNG round trip; PSNR and differing pixels against a known difference", "[render]") {
  Image a;
  a.width = 37;
  a.height = 21;
  a.rgba.resize(size_t(a.width) * a.height);
  std::mt19937 rng(3);
  for (auto& p : a.rgba) p = (rng() & 0x00ffffffu) | 0xff000000u;
  const std::string path = (std::filesystem::temp_directory_path() / "sphray_test_png.png").string();
  write_png(path, a);
  const Image b = read_png(path);
  CHECK(b.width == a.width);
  CHECK(b.height == a.height);
  CHECK(b.rgba == a.rgba);
  CHECK(std::isinf(psnr(a, b)));
  Image c = a;  // red off by exactly one level everywhere (never wrapping)
  for (auto& p : c.rgba) p = (p & 0xffffff00u) | (((p & 0xff) == 255 ? 254 : (p & 0xff) + 1));
  CHECK(psnr(a, c) == Approx(10 * std::log10(255.0 * 255.0 * 3.0)).margin(1e-9));
  CHECK(pixels_differing(a, c, 0) == a.rgba.size());
  CHECK(pixels_differing(a, c, 1) == 0);
  CHECK(pixels_differing(a, b, 0) == 0);
  std::remove(path.c_str());
  CHECK(error_of([&] { read_png(path); }).find("cannot read PNG") != std::string::npos);
  CHECK(error_of([&] { write_png("/nonexistent-dir/x.png", a); }).find("/nonexistent-dir/x.png") != std::string::npos);
}

TEST_CASE("render settings are validated", "[render][scene]") {
  const std::string base = test::source_path("scenes/dam_break.json");
  auto bad = [&](const std::string& set, const std::string& what) {
    const std::string e = error_of([&] { load_scene(base, {set}); });
    INFO(set << ": " << e);
    CHECK(e.find(what) != std::string::npos);
  };
  bad("render.interfaces=9", "render.interfaces");
  bad("render.interfaces=0", "render.interfaces");
  bad("render.step=0.6", "render.step");
  bad("render.step=0", "render.step");
  bad("render.width=10", "render.width");
  bad("render.ior=0.5", "render.ior");
  bad("render.absorption=[1,-1,0]", "render.absorption");
  bad("render.tint=[0.1,1.5,0]", "render.tint");
  bad("render.tint=0.2", "render.tint");
  bad("render.budget=0", "render.budget");
  bad("render.budget=65", "render.budget");
  bad("render.min_weight=-0.1", "render.min_weight");
  bad("render.reflections=2", "render.reflections");
  bad("render.eye=[0,-2,1]", "render.target");
  bad("render.fov=\"wide\"", "render.fov");
  bad("render.colour=1", "unknown key");
  bad("render.method=\"phong\"", "render.method");
  bad("render.method=\"phong\"", "\"raycast\", \"screen_space\", \"slices\"");
  bad("render.sphere_radius=0", "render.sphere_radius");
  bad("render.sphere_radius=5", "render.sphere_radius");
  bad("render.filter_width=0", "render.filter_width");
  bad("render.filter_width=17", "render.filter_width");
  bad("render.filter_iterations=-1", "render.filter_iterations");
  bad("render.filter_iterations=65", "render.filter_iterations");
  bad("render.slices=4", "render.slices");
  bad("render.slices=5000", "render.slices");
  const Scene ok = load_scene(base, {"render.interfaces=8", "render.step=0.25", "render.eye=[0,-2,1]",
                                     "render.target=[0.8,0.3,0.2]"});
  CHECK(ok.render.interfaces == 8);
  CHECK(ok.render.step == 0.25f);
  CHECK(ok.render.method == RenderMethod::Raycast);
  const Scene ss = load_scene(base, {"render.method=\"screen_space\"", "render.filter_iterations=20"});
  CHECK(ss.render.method == RenderMethod::ScreenSpace);
  CHECK(ss.render.filter_iterations == 20);
  CHECK(load_scene(base, {"render.method=\"slices\""}).render.method == RenderMethod::Slices);
}

TEST_CASE("still water a few centimetres deep stands out from the tiles with the default look", "[render]") {
  // A 3 cm pool on the floor of a 0.4 x 0.2 m tank, seen from the default
  // camera: inside the pool's outline (the camera rays that meet its box,
  // found in double) the mean colour of the default render lies at least 12
  // levels of 255 (Euclidean over r, g, b) from that of the empty tank. A
  // mean, so that the tiles merely shifted by refraction do not count.
  const test::StillPool pool;
  const Scene& s = pool.scene;
  const FieldSetup& fs = pool.fs;
  auto builder = make_cpu_field_builder(fs, FieldKind::Naive);
  const ParticleView pv = pool.particles.view();
  builder->build(pv);
  const Camera cam = make_camera(s.tank, s.render);
  const Environment env = make_environment(s.tank, fs.geom, cam);
  auto renderer = make_cpu_renderer();
  auto render = [&](const RenderSettings& r, const float* f, const ParticleView* v) {
    renderer->render(f, fs, cam, env, r);
    return renderer->download();
  };
  const std::vector<float> zero(size_t(fs.geom.nx) * fs.geom.ny * fs.geom.nz, 0.0f);
  const Image empty = render(s.render, zero.data(), nullptr);
  auto contrast = [&](const Image& img) {
    double sum[3] = {0, 0, 0};
    size_t n = 0;
    for (int y = 0; y < cam.height; ++y)
      for (int x = 0; x < cam.width; ++x) {
        const Vec3f d = cam.direction(float(x) + 0.5f, float(y) + 0.5f);
        const Vec3d e{cam.eye.x, cam.eye.y, cam.eye.z}, dd{d.x, d.y, d.z};
        double t0 = 0, t1 = 1e30;  // slab test against the pool's box
        const double lo[3] = {0, 0, 0}, hi[3] = {0.4, 0.2, 0.03}, oo[3] = {e.x, e.y, e.z}, dv[3] = {dd.x, dd.y, dd.z};
        for (int a = 0; a < 3; ++a) {
          const double ta = (lo[a] - oo[a]) / dv[a], tb = (hi[a] - oo[a]) / dv[a];
          t0 = std::max(t0, std::min(ta, tb));
          t1 = std::min(t1, std::max(ta, tb));
        }
        if (t0 > t1) continue;
        const size_t p = size_t(y) * cam.width + x;
        for (int c = 0; c < 3; ++c)
          sum[c] += double(int((img.rgba[p] >> (8 * c)) & 0xff) - int((empty.rgba[p] >> (8 * c)) & 0xff));
        ++n;
      }
    REQUIRE(n > 2000);
    return std::sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]) / double(n);
  };
  const double now = contrast(render(s.render, builder->data(), &pv));
  RenderSettings clear = s.render;  // water without tint or strong absorption: a glassy film
  clear.absorption = Vec3d{1.2, 0.35, 0.2};
  clear.tint = Vec3d{0, 0, 0};
  clear.reflections = false;
  const double glassy = contrast(render(clear, builder->data(), &pv));
  // (measured: 20.1 levels with the defaults, 7.2 for the clear film)
  INFO("mean colour shift inside the pool: " << now << " levels (a clear film: " << glassy << ")");
  CHECK(now >= 12.0);
  CHECK(glassy < 10.0);
}

TEST_CASE("an obstacle ends a path on its surface, in air and seen through the liquid", "[render][cpu]") {
  // A pier from the floor through the surface of a pool (half-space below z = 30).
  const AnalyticVolume v(half_space);
  const TriangleMesh pier = box_mesh({{20, 20, 0}, {28, 28, 40}});
  const MeshInput in = mesh_input(pier);
  const auto bvh = make_cpu_bvh(in.vertices, in.indices);
  auto tr = make_tracer(v, settings(4));
  tr.meshes.obstacles.mesh[0] = bvh->view();
  tr.meshes.obstacles.count = 1;  // world = voxel coordinates (origin 0, voxel 1)
  std::vector<Event> events;
  std::vector<Rgb> weights;
  auto sum = [&] {
    Rgb s{0, 0, 0};
    for (const Rgb& w : weights) s = s + w;
    return s;
  };
  // Straight down onto its top, above the water: the mesh's shade alone.
  Rgb c = tr.trace({24, 24, 47}, {0, 0, -1}, Watch{&events, &weights});
  const Rgb top = tr.meshes.shade({0, 0, 1}, tr.env.sun);
  CHECK(events.empty());
  CHECK(c.r == Approx(top.r).margin(1e-6));
  CHECK(c.g == Approx(top.g).margin(1e-6));
  CHECK(sum().r == Approx(1.0f));
  // Through the surface onto its side under water (face x = 20): the
  // reflected share takes the environment, the refracted share the pier.
  events.clear();
  weights.clear();
  const Vec3f d = unit_f(Vec3f{0.5f, 0, -1});
  c = tr.trace({10, 24, 40}, d, Watch{&events, &weights});
  REQUIRE(events.size() == 1);
  const Event& e = events[0];
  CHECK(e.p.z == Approx(30.0f).margin(0.05));
  // Snell in double: where the refracted ray meets x = 20, below the surface.
  Vec3d r;
  REQUIRE(refract_d(dbl(d), {0, 0, 1}, 1.0 / 1.33, r));
  const double t = (20.0 - e.p.x) / r.x;
  CHECK(e.p.z + t * r.z > 0.0);
  CHECK(e.p.z + t * r.z < 30.0);
  const Rgb side = tr.meshes.shade({-1, 0, 0}, tr.env.sun);
  const Rgb expect = tr.env(e.p, reflect(d, Vec3f{0, 0, 1})) * e.F + side * (1.0f - e.F);
  CHECK(c.r == Approx(expect.r).margin(2e-3));
  CHECK(c.g == Approx(expect.g).margin(2e-3));
  CHECK(c.b == Approx(expect.b).margin(2e-3));
  CHECK(sum().g == Approx(1.0f));
  // Moving (a Motion): drawn in its pose at the render's time. A quarter
  // period in, the pier has moved 10 voxels along +y: the ray down onto its
  // old top now meets the water, one 10 voxels over meets the top.
  tr.meshes.obstacles.motion[0].omega = 1.0f;
  tr.meshes.obstacles.motion[0].translate = {0, 10, 0};
  tr.meshes.at_time(float(M_PI / 2));
  events.clear();
  weights.clear();
  tr.trace({24, 22, 47}, {0, 0, -1}, Watch{&events, &weights});
  CHECK(events.size() >= 1);  // the water's surface
  events.clear();
  weights.clear();
  c = tr.trace({24, 34, 47}, {0, 0, -1}, Watch{&events, &weights});
  CHECK(events.empty());
  CHECK(c.r == Approx(top.r).margin(1e-5));
}
