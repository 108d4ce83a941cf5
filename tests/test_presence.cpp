// Particle presence against a double-precision brute-force reference, and the
// three cases of Yasuda et al. (deep ~1, free surface ~0 toward air, isolated 0),
// plus mirror symmetry.
#include <array>
#include <cmath>
#include <vector>

#include "catch.h"
#include "helpers.h"

using namespace sphray;

namespace {

constexpr double kDx = 0.01;

// A block of liquid n^3 at rest without gravity (so nothing moves in one step),
// plus optional extra particles; presence on. `varied`: densities spread over
// rho0 .. 1.03 rho0 instead of all rho0 (presence weighs by the particle's volume).
SolverInput lattice_input(int nx, int ny, int nz, const std::vector<Vec3d>& extra = {}, bool varied = false) {
  const std::string text = R"({"tank": {"min": [-0.1,-0.1,-0.1], "max": [0.4,0.4,0.4]},
    "gravity": [0,0,0], "sph": {"spacing": 0.01}, "run": {"end_time": 1}})";
  const Scene s = parse_scene(text, "presence.json");
  SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::EveryStep);
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        in.fluid_pos_rho.push_back(
            {float(i * kDx), float(j * kDx), float(k * kDx), varied ? 1000.0f + 10.0f * float((i * 7 + j * 3 + k * 5) % 4) : 1000.0f});
  for (const auto& e : extra) in.fluid_pos_rho.push_back({float(e.x), float(e.y), float(e.z), 1000.0f});
  in.fluid_vel.assign(in.fluid_pos_rho.size(), Float4{0, 0, 0, 0});
  return in;
}

// Presence by id after one step (computed at the initial positions).
std::vector<std::array<float, 6>> presence_of(const SolverInput& in) {
  auto s = make_cpu_solver(in);
  s->step(1e-6);
  const HostParticles p = s->download();
  REQUIRE(p.presence.size() == in.fluid_pos_rho.size());
  std::vector<std::array<float, 6>> by_id(p.presence.size());
  for (size_t k = 0; k < p.id.size(); ++k) by_id[p.id[k]] = p.presence[k];
  return by_id;
}

// One lobe of a particle inside a full lattice, in double: the normalisation.
double lattice_lobe(const SmoothingKernel<double>& k) {
  double sum = 0;
  for (int z = -6; z <= 6; ++z)
    for (int y = -6; y <= 6; ++y)
      for (int x = 1; x <= 6; ++x) {  // the mirror half space: the same sum
        const double d = kDx * x, r = kDx * std::sqrt(double(x * x + y * y + z * z));
        if (r < k.support()) sum += kDx * kDx * kDx * -k.dW_over_r(r) * d;
      }
  return sum;
}

// Independent reference in double: the definition in sph/interaction.h.
std::array<double, 6> reference_presence(const SolverInput& in, size_t i) {
  const auto k = SmoothingKernel<double>::make(KernelType::WendlandC2, double(in.params.kernel.h));
  const Float4 a = in.fluid_pos_rho[i];
  const double vol = double(in.params.particle_mass) / double(a.w), lobe = lattice_lobe(k);  // V_i = m / rho_i
  std::array<double, 6> acc{};
  for (size_t j = 0; j < in.fluid_pos_rho.size(); ++j) {
    if (j == i) continue;
    const Float4 b = in.fluid_pos_rho[j];
    const double d[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
    const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    const double r = std::sqrt(r2);
    if (r >= k.support() || r2 == 0) continue;
    // -W'(r) |cos| = -(dW/dr / r) |d_axis|
    for (int ax = 0; ax < 3; ++ax) acc[2 * ax + (d[ax] > 0 ? 0 : 1)] += vol * -k.dW_over_r(r) * std::abs(d[ax]);
  }
  for (auto& v : acc) v = std::min(1.0, v / lobe);
  return acc;
}

}  // namespace

TEST_CASE("the presence normalisation is about the continuous half-space value", "[presence][cpu]") {
  // For a continuous half space the lobe is pi int -W'(r) r^2 dr = 3 / (4h)
  // (Wendland C2): the lattice sum must come within the lattice's quadrature
  // error of it (-7.7% at h = 2 dx, -3.3% at h = 3 dx; -20% at 1.3 dx).
  for (const double ratio : {2.0, 3.0}) {
    const auto k = SmoothingKernel<double>::make(KernelType::WendlandC2, ratio * kDx);
    const double lobe = presence_lobe_on_lattice(k, kDx), continuous = 0.75 / k.h;
    INFO("h = " << ratio << " dx: lattice " << lobe << ", continuous " << continuous);
    CHECK(std::abs(lobe / continuous - 1.0) < 0.1);
    CHECK(std::abs(lobe / lattice_lobe(k) - 1.0) < 1e-12);
  }
}

TEST_CASE("presence equals the double-precision reference for every particle", "[presence][cpu]") {
  const SolverInput in = lattice_input(7, 6, 5, {{0.031, 0.027, 0.071}, {0.2, 0.2, 0.2}}, true);
  const auto got = presence_of(in);
  for (size_t i = 0; i < in.fluid_pos_rho.size(); ++i) {
    const auto ref = reference_presence(in, i);
    for (int d = 0; d < 6; ++d) REQUIRE(std::abs(got[i][d] - ref[d]) < 2e-4);
  }
}

TEST_CASE("presence is about 1 deep in the liquid, ~0 toward air, 0 when isolated", "[presence][cpu]") {
  const int n = 11;
  const SolverInput in = lattice_input(n, n, n, {{0.3, 0.3, 0.3}});
  const auto p = presence_of(in);
  auto at = [&](int i, int j, int k) { return p[size_t((k * n + j) * n + i)]; };
  // Deep: the centre particle.
  for (int d = 0; d < 6; ++d) CHECK(std::abs(at(5, 5, 5)[d] - 1.0f) < 0.05f);
  // Free surface (top face, centre): nothing above, full liquid below, in
  // between sideways (0.5 for a continuous half space; the surface layer
  // itself adds to the lateral lobes on a lattice: about 0.69 at h = 2 dx).
  const auto top = at(5, 5, n - 1);
  CHECK(top[4] < 0.02f);                  // +z, toward air
  CHECK(std::abs(top[5] - 1.0f) < 0.05f); // -z, into the liquid
  for (int d = 0; d < 4; ++d) CHECK((top[d] > 0.4f && top[d] < 0.85f));
  // Isolated.
  for (int d = 0; d < 6; ++d) CHECK(p.back()[d] == 0.0f);
}

TEST_CASE("pbf and dfsph presence: 1 deep in the liquid, ~0 toward air, 0 when isolated", "[presence][cpu]") {
  // Their own kernels and calibrated volumes (make_pbf_params, make_dfsph_params):
  // a full lattice gives each lobe exactly its normalisation.
  const std::string kind = GENERATE(std::string("pbf"), std::string("dfsph"));
  INFO("sph.solver " << kind);
  const Scene s = parse_scene(R"({"tank": {"min": [-0.1,-0.1,-0.1], "max": [0.4,0.4,0.4]}, "gravity": [0,0,0],
    "fluid": [{"min": [0,0,0], "max": [0.11,0.11,0.11]}, {"min": [0.3,0.3,0.3], "max": [0.31,0.31,0.31]}],
    "sph": {"spacing": 0.01, "solver": ")" + kind + R"("}, "run": {"end_time": 1}})", "presence.json");
  auto solver = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::EveryStep));
  solver->step(1e-6);
  const HostParticles p = solver->download();
  REQUIRE(p.presence.size() == 11 * 11 * 11 + 1);
  auto near = [&](double x, double y, double z) {
    for (size_t k = 0; k < p.pos.size(); ++k)
      if (length(p.pos[k] - Vec3f{float(x), float(y), float(z)}) < 1e-4f) return p.presence[k];
    FAIL("no particle at (" << x << ", " << y << ", " << z << ")");
    return std::array<float, 6>{};
  };
  const auto deep = near(0.055, 0.055, 0.055), top = near(0.055, 0.055, 0.105), alone = near(0.305, 0.305, 0.305);
  INFO("top lobes " << top[0] << " " << top[1] << " " << top[2] << " " << top[3] << " " << top[4] << " " << top[5]);
  for (int d = 0; d < 6; ++d) CHECK(std::abs(deep[d] - 1.0f) < 0.01f);
  CHECK(top[4] < 0.02f);                  // +z, toward air
  CHECK(std::abs(top[5] - 1.0f) < 0.01f); // -z, into the liquid
  for (int d = 0; d < 4; ++d) CHECK((top[d] > 0.4f && top[d] < 0.85f));
  for (int d = 0; d < 6; ++d) CHECK(alone[d] == 0.0f);
}

TEST_CASE("presence is mirror symmetric", "[presence][cpu]") {
  // An irregular cluster and its mirror image in x: +x and -x swap, the rest agree.
  std::vector<Vec3d> pts = {{0, 0, 0}, {0.008, 0.001, 0}, {0.015, -0.004, 0.003}, {0.004, 0.009, -0.002}, {-0.007, 0.002, 0.006}};
  SolverInput a = lattice_input(0, 0, 0, pts);
  for (auto& p : pts) p.x = -p.x;
  SolverInput b = lattice_input(0, 0, 0, pts);
  const auto pa = presence_of(a), pb = presence_of(b);
  for (size_t i = 0; i < pts.size(); ++i) {
    CHECK(std::abs(pa[i][0] - pb[i][1]) < 1e-5f);
    CHECK(std::abs(pa[i][1] - pb[i][0]) < 1e-5f);
    for (int d = 2; d < 6; ++d) CHECK(std::abs(pa[i][d] - pb[i][d]) < 1e-5f);
  }
}

TEST_CASE("presence costs nothing when no stage needs it", "[presence][cpu]") {
  SolverInput in = lattice_input(5, 5, 5);
  auto with = make_cpu_solver(in);
  in.presence = PresenceMode::Off;
  auto without = make_cpu_solver(in);
  CHECK_FALSE(with->has_presence());  // nothing computed before the first step
  // Presence and its re-sort scratch, six floats each per particle.
  CHECK(with->device_bytes() - without->device_bytes() == 2 * 6 * sizeof(float) * 125);
  with->step(1e-6);
  without->step(1e-6);
  CHECK(with->has_presence());
  CHECK_FALSE(without->has_presence());
  CHECK(without->download().presence.empty());
  CHECK(without->view().presence == nullptr);
}
