#include "skin.h"
#include "forwarding_solver.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Dense>

namespace sphray {

namespace {

// Kira et al.'s eight-neighbour stencil: edge neighbours 2/3, diagonals 1/3,
// each over its distance squared (exact for quadratics on a square grid).
constexpr double kEdgeWeight = 2.0 / 3.0, kDiagonalWeight = 1.0 / 3.0;

// The render surface is refined to the texel spacing, within this many triangles.
constexpr size_t kMaxSurfaceTriangles = size_t(1) << 18;

// Least-squares Laplacian weights: the quadratic through a texel's
// neighbours (offsets in its tangent plane, weighted by 1 / d^2) fitted for
// h_q - h = g.x + x^T H x / 2; lap = trace H as weights on h_q - h.
std::array<double, kSkinNeighbours> fitted_laplacian(const std::array<Vec3d, kSkinNeighbours>& r, Vec3d n,
                                                     const std::array<bool, kSkinNeighbours>& use) {
  const Vec3d a = std::abs(n.x) < 0.9 ? Vec3d{1, 0, 0} : Vec3d{0, 1, 0};
  const Vec3d t1 = normalized(cross(n, a));
  const Vec3d t2 = cross(n, t1);
  Eigen::Matrix<double, kSkinNeighbours, 5> A = Eigen::Matrix<double, kSkinNeighbours, 5>::Zero();
  Eigen::Matrix<double, kSkinNeighbours, 1> w = Eigen::Matrix<double, kSkinNeighbours, 1>::Zero();
  for (int q = 0; q < kSkinNeighbours; ++q) {
    if (!use[q]) continue;
    const double x = dot(r[q], t1), y = dot(r[q], t2), d2 = dot(r[q], r[q]);
    A.row(q) << x, y, 0.5 * x * x, x * y, 0.5 * y * y;
    w(q) = 1.0 / d2;
  }
  const Eigen::Matrix<double, 5, 5> N = A.transpose() * w.asDiagonal() * A;
  const Eigen::Matrix<double, 5, kSkinNeighbours> P = N.ldlt().solve(A.transpose() * w.asDiagonal());
  std::array<double, kSkinNeighbours> out{};
  for (int q = 0; q < kSkinNeighbours; ++q) out[q] = P(2, q) + P(4, q);
  return out;
}

}  // namespace

SkinGeometry make_skin_geometry(const SkinInput& in) {
  SkinGeometry g;
  g.input = in;
  g.map = make_skin_map(in.mesh, in.params.resolution, in.embedding);
  int levels = 0;
  while (levels < 6 && in.mesh.size() << (2 * (levels + 1)) <= kMaxSurfaceTriangles) ++levels;
  g.surface = skin_surface(in.mesh, g.map.embedding, g.map.mean_spacing, levels);

  const size_t n = g.map.size();
  const double s2 = double(in.params.wave_speed) * in.params.wave_speed;
  g.point.resize(n);
  g.neighbour.resize(n * kSkinNeighbours);
  g.coef.resize(n * kSkinNeighbours);
  double lambda_max = 0;
  for (size_t i = 0; i < n; ++i) {
    g.point[i] = to_f(g.map.point[i]);
    double diag = 0;
    std::array<double, kSkinNeighbours> fit{};
    bool fitted_here = in.params.stencil == SkinStencil::Fitted;
    if (fitted_here) {
      std::array<Vec3d, kSkinNeighbours> r{};
      std::array<bool, kSkinNeighbours> use{};
      for (int q = 0; q < kSkinNeighbours; ++q) {
        r[q] = g.map.point[g.map.neighbour[i][q]] - g.map.point[i];
        use[q] = g.map.neighbour[i][q] != i;
      }
      fit = fitted_laplacian(r, g.map.normal[i], use);
      // A negative weight (a skewed or squeezed neighbourhood) can make the
      // scheme grow without bound: that texel keeps the paper's weights.
      if (*std::min_element(fit.begin(), fit.end()) < 0.0) {
        fitted_here = false;
        ++g.unfitted;
      }
    }
    for (int q = 0; q < kSkinNeighbours; ++q) {
      const uint32_t nb = g.map.neighbour[i][q];
      const double d = in.params.stencil == SkinStencil::Texture ? g.map.mean_spacing * (q < 4 ? 1.0 : std::sqrt(2.0))
                                                                 : g.map.distance[i][q];
      double c = (nb == i || d <= 0.0) ? 0.0 : s2 * (q < 4 ? kEdgeWeight : kDiagonalWeight) / (d * d);
      if (fitted_here) c = s2 * fit[q];
      g.neighbour[i * kSkinNeighbours + q] = nb;
      g.coef[i * kSkinNeighbours + q] = float(c);
      diag += c;
    }
    lambda_max = std::max(lambda_max, 2.0 * diag);  // Gershgorin's bound on the stencil's spectrum
  }
  const Box box = bounds(in.mesh);
  g.size = length(box.max - box.min);
  const double omega = 2.0 * M_PI * in.params.frequency;
  // Symplectic Euler is stable for dt^2 lambda <= 4; a fifth kept in hand.
  g.max_substep = 0.8 * 2.0 / std::sqrt(lambda_max + omega * omega);
  return g;
}

std::vector<Vec3f> SkinSet::displaced(size_t k) const { return displaced_surface(geo_[k], heights(k)); }

std::vector<Vec3f> displaced_surface(const SkinGeometry& g, const std::vector<float>& h) {
  std::vector<Vec3f> out(g.surface.mesh.vertices.size());
#pragma omp parallel for schedule(static)
  for (size_t v = 0; v < out.size(); ++v)
    out[v] = to_f(g.surface.mesh.vertices[v] + g.surface.normal[v] * g.map.sample(h, g.surface.direction[v]));
  return out;
}

namespace {

class SkinnedSolver final : public ForwardingSolver {
 public:
  SkinnedSolver(std::unique_ptr<Solver> inner, std::unique_ptr<SkinSet> skins)
      : ForwardingSolver(std::move(inner)), skins_(std::move(skins)) {
    interval_ = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < skins_->size(); ++k) interval_ = std::min(interval_, 0.5 * skins_->geometry(k).max_substep);
    if (inner_->kind() != SolverKind::Wcsph) interval_ = 0;
  }

  // Under WCSPH the skins advance once their own step's worth of time has
  // passed (half the stablest skin's substep limit), the load sampled then:
  // its pressure follows the density smoothly, and its acoustic steps are
  // many per skin step. Under DFSPH they advance every step: the pressure
  // of one step is noisy (the solve stops at a tolerance), and the skins'
  // damped response averages it only if it sees every step.
  void step(double until) override {
    const double t0 = inner_->time();
    inner_->step(until);
    pending_ += inner_->time() - t0;
    times_ = inner_->last_stage_times();
    if (pending_ < interval_) return;
    skins_->advance(inner_->view(), inner_->device_pressure(), inner_->time(), pending_);
    pending_ = 0;
    times_.skin = skins_->last_ms();
  }
  const StageTimes& last_stage_times() const override { return times_; }
  SkinSet* skins() override { return skins_.get(); }
  const SkinSet* skins() const override { return skins_.get(); }
  // A run over several ranks cannot carry skins (make_slab_solver refuses them).
  void set_slab(const SlabBounds&) override { throw std::logic_error("an obstacle's skin waves cannot run over several ranks"); }

 private:
  std::unique_ptr<SkinSet> skins_;
  StageTimes times_{};
  double interval_ = 0, pending_ = 0;
};

}  // namespace

std::unique_ptr<Solver> with_skins(std::unique_ptr<Solver> inner, const std::vector<SkinInput>& skins,
                                   const SphParams& prm) {
  if (skins.empty()) return inner;
  if (inner->kind() == SolverKind::Pbf)
    throw std::invalid_argument("obstacle skins need a solver with a pressure (wcsph or dfsph), not pbf");
  std::vector<SkinGeometry> geo;
  for (const SkinInput& k : skins) geo.push_back(make_skin_geometry(k));
  std::unique_ptr<SkinSet> set = inner->backend() == Backend::Cuda ? make_cuda_skin_set(std::move(geo), prm)
                                                                   : make_cpu_skin_set(std::move(geo), prm);
  return std::make_unique<SkinnedSolver>(std::move(inner), std::move(set));
}

}  // namespace sphray
