// Runs over several ranks (dist/): the slab plan against brute-force
// counts, and the dam break on 1, 2 and 3 MPI ranks (mpirun, CPU backend)
// against the one-rank run.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>

#include "catch.h"
#include "dist/rank_export.h"
#include "dist/slab_solver.h"
#include "dist/slabs.h"
#include "helpers.h"
#include "io/frames_h5.h"
#include "render/image.h"

using namespace sphray;
using namespace sphray::test;

namespace {

// How many of xs lie in [a, b).
size_t count_in(const std::vector<double>& xs, double a, double b) {
  return size_t(std::count_if(xs.begin(), xs.end(), [&](double x) { return x >= a && x < b; }));
}

}  // namespace

TEST_CASE("slab cuts split the particles into equal counts, at least a halo apart", "[dist]") {
  std::mt19937 rng(7);
  // Liquid in the first quarter of a 1.6 m domain, its density growing
  // linearly toward x = 0.4 m (skewed, as a collapsing column).
  std::vector<double> xs(20000);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double& x : xs) x = 0.4 * std::sqrt(u(rng));
  const double lo = 0, hi = 1.6, bin = 0.005;
  AxisHistogram h = AxisHistogram::over(lo, hi, bin);
  for (double x : xs) h.add(x);
  SECTION("wide slabs: each rank owns 1 / ranks of the particles, to a bin's worth") {
    for (int ranks : {2, 3, 5}) {
      const std::vector<double> cuts = balanced_cuts(h, ranks, lo, hi, 0.01);
      REQUIRE(cuts.size() == size_t(ranks - 1));
      REQUIRE(std::is_sorted(cuts.begin(), cuts.end()));
      std::vector<double> edges{-1e9};
      edges.insert(edges.end(), cuts.begin(), cuts.end());
      edges.push_back(1e9);
      for (int r = 0; r < ranks; ++r) {
        const double share = double(count_in(xs, edges[size_t(r)], edges[size_t(r) + 1])) / double(xs.size());
        // The interpolation within a bin assumes its particles are spread
        // evenly: off by at most the densest bin's share.
        const double densest = *std::max_element(h.counts.begin(), h.counts.end()) / double(xs.size());
        CHECK(std::abs(share - 1.0 / ranks) <= densest);
      }
    }
  }
  SECTION("narrow liquid: the cuts move apart to the least width, inside the domain") {
    const double width = 0.32;
    const std::vector<double> cuts = balanced_cuts(h, 5, lo, hi, width);
    CHECK(cuts.front() >= lo + width - 1e-12);
    CHECK(cuts.back() <= hi - width + 1e-12);
    for (size_t k = 1; k < cuts.size(); ++k) CHECK(cuts[k] - cuts[k - 1] >= width - 1e-12);
  }
}

TEST_CASE("the most particles a rank holds with its ghosts, from the histogram, is the brute-force count", "[dist]") {
  std::mt19937 rng(11);
  std::vector<double> xs(30000);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double& x : xs) x = 0.2 + 0.5 * u(rng) * u(rng);  // skewed toward 0.2
  const double lo = 0, hi = 1.0, bin = 0.002, halo = 0.03;
  AxisHistogram h = AxisHistogram::over(lo, hi, bin);
  for (double x : xs) h.add(x);
  for (int ranks : {1, 2, 4, 7}) {
    const std::vector<double> cuts = balanced_cuts(h, ranks, lo, hi, 2 * halo);
    double most = 0, densest = 0;
    for (int r = 0; r < ranks; ++r) {
      const double a = r == 0 ? -1e9 : cuts[size_t(r) - 1] - halo, e = r == ranks - 1 ? 1e9 : cuts[size_t(r)] + halo;
      most = std::max(most, double(count_in(xs, a, e)));
    }
    for (double c : h.counts) densest = std::max(densest, c);
    INFO(ranks << " ranks");
    // Each end of a slab interpolates within one bin: off by a bin's worth at each.
    CHECK(std::abs(most_held(h, cuts, halo) - most) <= 2 * densest);
    if (ranks == 1) CHECK(most_held(h, cuts, halo) == double(xs.size()));
  }
}

TEST_CASE("the slabs are cut along the axis whose busiest rank holds the fewest particles", "[dist]") {
  // The dam break's column (0.4 x 0.67 x 0.3 m in a 1.6 x 0.67 x 0.6 m tank)
  // at 4 cm: slabs at least 0.32 m thick (two WCSPH supports). Along x 5 fit,
  // along y 2, along z 1.
  const Scene s = load_scene(source_path("scenes/dam_break.json"), {"sph.spacing=0.04"});
  const SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
  // Brute force: the particles each rank holds (its slab widened by halo_free
  // on each side), the most of any rank.
  auto busiest = [&](const SlabPlan& p) {
    size_t most = 0;
    for (int r = 0; r < p.ranks(); ++r) {
      const double a = r == 0 ? -1e9 : p.slab_lo(r) - p.halo_free, e = r == p.ranks() - 1 ? 1e9 : p.slab_hi(r) + p.halo_free;
      size_t n = 0;
      for (const Float4& q : in.fluid_pos_rho) {
        const double x = along(xyz(q), p.axis);
        n += x >= a && x < e;
      }
      most = std::max(most, n);
    }
    return double(most);
  };
  const SlabPlan x2 = plan_slabs(in, 2, 0), y2 = plan_slabs(in, 2, 1), auto2 = plan_slabs(in, 2);
  CHECK(x2.axis == 0);
  CHECK(y2.axis == 1);
  // Cut across x (the column's 0.67 x 0.3 m section) a rank holds more than
  // across y (0.4 x 0.3 m).
  INFO("busiest rank: x " << busiest(x2) << ", y " << busiest(y2));
  CHECK(busiest(y2) < busiest(x2));
  CHECK(auto2.axis == 1);
  CHECK(auto2.cuts == y2.cuts);
  CHECK(std::abs(auto2.held[0] - busiest(x2)) <= 0.02 * busiest(x2));
  CHECK(std::abs(auto2.held[1] - busiest(y2)) <= 0.02 * busiest(y2));
  CHECK(auto2.held[2] == 0);  // 0.6 m hold one slab of 0.32 m
  CHECK(x2.held[1] == auto2.held[1]);  // an axis asked for: the others' counts given too
  // Three slabs fit along x alone.
  CHECK(plan_slabs(in, 3).axis == 0);
  CHECK(plan_slabs(in, 1).axis == 0);  // one rank: the longest axis
  // An axis asked for that cannot hold them, and a rank count no axis holds.
  try {
    plan_slabs(in, 2, 2);
    FAIL("2 slabs of 0.32 m fit in 0.6 m");
  } catch (const std::invalid_argument& e) {
    CHECK(has(e.what(), "2 ranks need slabs at least 0.32 m thick"));
    CHECK(has(e.what(), "along z, which is 0.6 m long: at most 1 ranks"));
  }
  try {
    plan_slabs(in, 6);
    FAIL("6 slabs of 0.32 m fit in 1.6 m");
  } catch (const std::invalid_argument& e) {
    CHECK(has(e.what(), "along the domain's longest axis (x), which is 1.6 m long: at most 5 ranks"));
  }
}

TEST_CASE("a run over several ranks refuses particle ids of more than 30 bits", "[dist]") {
  // The refresh lists of PBF and DFSPH sort (list, id) keys of 32 bits.
  const Scene s = load_scene(source_path("scenes/dam_break.json"), {"sph.spacing=0.04", "sph.solver=pbf"});
  SolverInput in = make_solver_input(resolve_scene(s), PresenceMode::Off);
  in.fluid_id.resize(in.fluid_pos_rho.size());
  std::iota(in.fluid_id.begin(), in.fluid_id.end(), (1u << 30) - 5u);
  const auto comm = make_single_comm();
  try {
    make_slab_solver(in, plan_slabs(in, 1), *comm, Backend::Cpu, SolverMaker(make_cpu_solver));
    FAIL("ids from 2^30 - 5 were taken");
  } catch (const std::invalid_argument& e) {
    CHECK(has(e.what(), "particle ids below 2^30 (1,073,741,824); id 1073741824 is not"));
  }
}

TEST_CASE("each particle's owner and ghost copies agree with brute force", "[dist]") {
  SlabPlan p;
  p.lo = 0;
  p.hi = 1.6;
  p.halo = p.min_width = 0.3;
  p.halo_free = 0.15;
  p.cuts = {0.4, 0.8, 1.2};
  for (int me = 0; me < p.ranks(); ++me) {
    const SlabBounds b = slab_bounds(p, me);
    for (double x = -0.1; x < 1.7; x += 0.0137) {
      int owner = 0;
      while (owner < 3 && x >= p.cuts[size_t(owner)]) ++owner;
      if (std::abs(owner - me) > 1) continue;  // a step moves a particle into a neighbour's slab at most
      for (bool near_walls : {false, true}) {
        const Destinations d = destinations_of(b, Float4{float(x), 0.5f, 0.5f, 1000.0f}, near_walls);
        INFO("rank " << me << ", x = " << x << (near_walls ? ", near walls" : ""));
        CHECK(int(d.owner) == owner - me + kSelf);
        for (int r = 0; r < p.ranks(); ++r) {
          const double a = r == 0 ? -1e9 : p.cuts[size_t(r) - 1], e = r == 3 ? 1e9 : p.cuts[size_t(r)];
          const double gap = x < a ? a - x : x >= e ? x - e : 0.0;
          const bool wanted = r == owner || gap < (near_walls ? p.halo : p.halo_free);
          const int k = r - me + kSelf;
          CHECK(((k >= 0 && k < kPeers) && ((d.to >> k) & 1u)) == wanted);
        }
      }
    }
  }
}

TEST_CASE("each solver counts its particles along an axis as the host bins them", "[dist]") {
  // The balance's histogram on the solver's backend (axis_counts) against
  // the host's binning of the downloaded particles (Solver's default).
  for (const char* solver : {"wcsph", "pbf", "dfsph"}) {
    INFO(solver);
    const Scene s = load_scene(source_path("scenes/dam_break.json"),
                               {"sph.spacing=0.04", std::string("sph.solver=") + solver});
    auto sv = make_cpu_solver(make_solver_input(resolve_scene(s), PresenceMode::Off));
    for (int k = 0; k < 5; ++k) sv->step(1.0);
    for (int axis : {0, 1, 2}) {
      // Bins of 3 cm from 0.1 m: the first and last bins hold those beyond.
      const std::vector<double> got = sv->axis_counts(axis, 0.1, 0.03, 12),
                                ref = sv->Solver::axis_counts(axis, 0.1, 0.03, 12);
      CHECK(got == ref);
      CHECK(std::accumulate(got.begin(), got.end(), 0.0) == double(sv->num_fluid()));
    }
  }
}

TEST_CASE("the id blocks of an export written by every rank cover every id once", "[dist]") {
  for (const uint64_t m : {1ull, 2ull, 7ull, 100ull, 1120ull, 983940ull})
    for (const int ranks : {1, 2, 3, 4, 7, 8}) {
      const IdBlocks b{m, ranks};
      INFO(m << " ids over " << ranks << " ranks");
      CHECK(b.lo(0) == 0);
      CHECK(b.lo(ranks) == m);
      // Brute force: the owner is the r whose [lo(r), lo(r + 1)) holds the id;
      // every id has one, and the blocks differ by at most one id.
      const uint64_t step = std::max<uint64_t>(1, m / 5000);
      for (uint64_t id = 0; id < m; id += step) {
        int owner = -1;
        for (int r = 0; r < ranks; ++r)
          if (b.lo(r) <= id && id < b.lo(r + 1)) owner = r;
        REQUIRE(b.owner(uint32_t(id)) == owner);
      }
      for (int r = 0; r + 1 < ranks; ++r) {
        const uint64_t w0 = b.lo(r + 1) - b.lo(r), w1 = b.lo(r + 2) - b.lo(r + 1);
        CHECK((w0 > w1 ? w0 - w1 : w1 - w0) <= 1);
      }
    }
}

TEST_CASE("a rank count the domain cannot hold is refused with the numbers", "[dist]") {
  CHECK_NOTHROW(check_rank_count(5, 0.0, 1.6, 0.32, "x"));
  try {
    check_rank_count(6, 0.0, 1.6, 0.32, "x");
    FAIL("6 slabs of 0.32 m fit in 1.6 m");
  } catch (const std::invalid_argument& e) {
    CHECK(has(e.what(), "6 ranks"));
    CHECK(has(e.what(), "0.32 m"));
    CHECK(has(e.what(), "1.6 m"));
    CHECK(has(e.what(), "at most 5 ranks"));
  }
}

#if defined(SPHRAY_MPIEXEC)
namespace {

// `sphray COMMAND ARGS` (default run) on `ranks` MPI ranks (CPU backend, one OpenMP thread each,
// oversubscribing the cores), exported to out: its exit code and output.
CliResult run_ranks(int ranks, const std::string& args, const std::string& command = "run") {
  setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  setenv("OMPI_MCA_rmaps_base_oversubscribe", "1", 1);
  setenv("OMP_NUM_THREADS", "1", 1);
  const std::string out = tmp_dir() + "/mpirun_output.txt";
  const std::string cmd = std::string(SPHRAY_MPIEXEC) + " -n " + std::to_string(ranks) + " " + SPHRAY_EXE +
                          " " + command + " " + args + " > " + out + " 2>&1";
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out)};
}

// `sphray run ARGS OUT1` on one rank and `ARGS OUT2` on two; both must
// succeed. Returns the two-rank run's output.
std::string run_on_1_and_2(const std::string& args, const std::string& out1, const std::string& out2) {
  const CliResult r1 = run_ranks(1, args + out1), r2 = run_ranks(2, args + out2);
  INFO(r1.output << r2.output);
  REQUIRE(r1.code == 0);
  REQUIRE(r2.code == 0);
  return r2.output;
}

// `sphray COMMAND ARGS` on 2 ranks is refused as bad input: exit code 2,
// `message` in its output.
void check_refused_on_2_ranks(const std::string& args, const std::string& message,
                              const std::string& command = "run") {
  const CliResult r = run_ranks(2, args, command);
  INFO(r.output);
  CHECK(r.code == 2);
  CHECK(has(r.output, message));
}

// The rows of a metrics CSV (after its header), as numbers.
std::vector<std::vector<double>> metrics_rows(const std::string& path) {
  std::vector<std::vector<double>> rows;
  std::istringstream in(slurp(path));
  std::string line;
  std::getline(in, line);  // the header
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) row.push_back(std::stod(cell));
    rows.push_back(row);
  }
  return rows;
}

double kinetic_energy(const Frame& f) {
  double e = 0;
  for (float v : f.velocity) e += 0.5 * double(v) * double(v);
  return e;  // per unit particle mass
}

// The dam break at 4 cm on 1, 2 and 3 ranks with `solver_args`: every rank
// count keeps every particle (the one-rank run's ids in every frame, none
// twice), takes the same steps, and follows the one-rank run: positions
// within `early` spacings up to t = 0.1 s (20 steps or more) and `offset`
// after, the front within `front` spacings, kinetic energy within `energy`
// (relative).
struct Follows {
  double early, offset, front, energy;
};
void check_ranks_follow_one_rank(const std::string& solver_args, const std::string& tag, const Follows& bound) {
  const double spacing = 0.04;
  const std::string scene = source_path("scenes/dam_break.json");
  const std::string summary = tmp_dir() + "/summary.json";  // rank 0's alone
  const std::string args = scene + " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.6 "
                                   "--set run.output_interval=0.1 --summary-json " + summary + " " + solver_args +
                           " --export-fields velocity,density --export ";
  auto path = [&](const std::string& what, int ranks) {
    return tmp_dir() + "/" + tag + what + std::to_string(ranks);
  };
  const CliResult r1 = run_ranks(1, "--metrics-csv " + path("metrics", 1) + ".csv " + args + path("ranks", 1) + ".h5");
  INFO(r1.output);
  REQUIRE(r1.code == 0);
  CHECK(has(slurp(summary), "\"max_speed_particle\""));  // one rank knows where its largest speed was
  const FrameReader ref(path("ranks", 1) + ".h5");
  REQUIRE(ref.frames().size() == 7);
  for (int ranks : {2, 3}) {
    const CliResult r =
        run_ranks(ranks, "--metrics-csv " + path("metrics", ranks) + ".csv " + args + path("ranks", ranks) + ".h5");
    INFO(ranks << " ranks: " << r.output);
    REQUIRE(r.code == 0);
    // The metrics rows (rank 0's sums over the gathered particles): the same
    // front and kinetic energy to the bounds.
    const auto m1 = metrics_rows(path("metrics", 1) + ".csv"), mr = metrics_rows(path("metrics", ranks) + ".csv");
    REQUIRE(mr.size() == m1.size());
    for (size_t k = 0; k < m1.size(); ++k) {
      CHECK(mr[k][2] == m1[k][2]);                                           // particles
      CHECK(std::abs(mr[k][3] - m1[k][3]) <= bound.front * spacing);                    // front
      CHECK(std::abs(mr[k][4] - m1[k][4]) <= bound.energy * std::max(m1[k][4], 1e-9));  // kinetic energy
    }
    // Two slabs fit along y, the column's longer side and the fewer ghosts;
    // three along x alone (slabs.h).
    CHECK(has(r.output, "ranks: " + std::to_string(ranks) + " slabs along " + (ranks == 2 ? "y" : "x")));
    CHECK(has(slurp(summary), "\"status\": \"completed\""));
    CHECK_FALSE(has(slurp(summary), "\"max_speed_particle\""));  // it may have been another rank's
    const FrameReader got(path("ranks", ranks) + ".h5");
    REQUIRE(got.frames().size() == ref.frames().size());
    for (size_t k = 0; k < ref.frames().size(); ++k) {
      const Frame a = ref.read(k), b = got.read(k);
      INFO("frame " << k << " (t = " << b.time << " s)");
      CHECK(b.time == a.time);
      CHECK(b.step == a.step);  // one dt for all ranks: the same steps
      // Every particle once: the ids of the one-rank run, ascending, none
      // twice (the export sorts by id), so the mass is the same too.
      REQUIRE(b.id == a.id);
      double worst = 0;
      for (size_t i = 0; i < a.position.size(); ++i)
        worst = std::max(worst, std::abs(double(a.position[i]) - double(b.position[i])));
      CHECK(worst <= (a.time <= 0.1 + 1e-9 ? bound.early : bound.offset) * spacing);
      const double ea = kinetic_energy(a), eb = kinetic_energy(b);
      CHECK(std::abs(eb - ea) <= bound.energy * std::max(ea, 1e-9));
    }
  }
}

}  // namespace

TEST_CASE("the dam break on 2 and 3 ranks keeps every particle and follows the one-rank run", "[dist][mpi]") {
  // Round-off: the ranks add a particle's neighbours in another order
  // (ghosts enter the sort after the owned), float sums differ in the last
  // bits and the flow's chaos grows that. Measured at 0.6 s: 2.1e-6 m at
  // most (5e-5 spacings; 2 ranks cut along y, 3 along x: slabs.h). A lost or doubled neighbour moves a particle by a
  // good part of a spacing within a few steps; 1e-3 spacings lies between
  // the two.
  check_ranks_follow_one_rank("", "wcsph", {1e-3, 1e-3, 1e-3, 1e-5});
}

TEST_CASE("PBF on 2 and 3 ranks keeps every particle and follows the one-rank run", "[dist][mpi]") {
  // The ghosts take their owners' values after every pass, so the ranks
  // compute what one rank does but for the order of the sums, as WCSPH.
  // PBF amplifies that round-off far more than WCSPH (its projections are
  // one-sided and capped: an ulp decides whether a splash particle is
  // corrected; mirrored wall images, whose lambdas couple a wall particle
  // to its neighbours as in the bulk, let it grow faster than static ones).
  // Measured, largest position difference: on 3 ranks 3e-8 m at 0.1 s
  // (7.5e-7 spacings), 1.4e-4 m at 0.2 s, 1.1e-2 m at 0.5 s and 4.1e-2 m
  // (1 spacing: a splash particle) at 0.6 s; on 2, none. So: round-off
  // bounds for the first 20 steps, where a lost or doubled neighbour at the
  // cuts (present from the first step) would show as 1e-4 spacings or more,
  // and the chaos's own size after.
  check_ranks_follow_one_rank("--set sph.solver=pbf", "pbf", {1e-4, 1.5, 0.05, 2e-3});
}

TEST_CASE("DFSPH on 2 and 3 ranks keeps every particle and follows the one-rank run", "[dist][mpi]") {
  // As PBF: the ghosts take their owners' velocities, pressures and
  // accelerations before every pass that reads them, and the residuals are
  // summed over the ranks, so the ranks iterate alike, but for round-off.
  // At the default tolerances (0.1%) a residual that differs in its last
  // bits ends a solve one iteration sooner or later, which moves the
  // particles by the tolerance's worth (2 ranks: 6e-8 m until the 9th step,
  // then 1e-5 m); at 1e-5 the solves iterate alike, so the comparison sees
  // the round-off itself. Measured at 1e-5 on 2 and 3 ranks: 1.2e-7 m at
  // 0.1 s (3e-6 spacings), then growing to 9e-5 and 1.5e-3 m at 0.6 s
  // (0.04 spacings); front within 2.1e-6 m, kinetic energy within 9e-6.
  check_ranks_follow_one_rank("--set sph.solver=dfsph --set dfsph.tolerance=1e-5 --set dfsph.divergence_tolerance=1e-5",
                              "dfsph", {1e-4, 0.1, 1e-3, 1e-4});
}

// The largest distance between a particle's positions in frames a and b (same ids).
double largest_offset(const Frame& a, const Frame& b) {
  REQUIRE(a.id == b.id);
  double worst = 0;
  for (size_t i = 0; i < a.position.size(); ++i)
    worst = std::max(worst, std::abs(double(a.position[i]) - double(b.position[i])));
  return worst;
}

// `args` (ending in --export) on 1 and 2 ranks, into TAG1.h5 and TAG2.h5:
// both write `frames` frames, and each frame of the 2-rank run is at the
// one-rank run's step, its particles within `bound` metres of theirs.
void check_2_ranks_follow(const std::string& args, const std::string& tag, size_t frames, double bound) {
  const std::string one = tmp_dir() + "/" + tag + "1.h5", two = tmp_dir() + "/" + tag + "2.h5";
  run_on_1_and_2(args, one, two);
  const FrameReader a(one), b(two);
  REQUIRE(a.frames().size() == frames);
  REQUIRE(b.frames().size() == frames);
  for (size_t k = 0; k < frames; ++k) {
    const Frame fa = a.read(k), fb = b.read(k);
    INFO("frame " << k);
    CHECK(fb.step == fa.step);
    CHECK(largest_offset(fa, fb) <= bound);
  }
}

TEST_CASE("ghosts one support wide away from the walls change nothing", "[dist][mpi]") {
  // A column wide and deep enough that its middle lies beyond the walls'
  // reach (cells of wall particles' neighbours): there a rank copies only
  // one support of its neighbour's particles; 2 ranks against 1.
  const double spacing = 0.04;
  const std::string args = source_path("scenes/dam_break.json") +
                           " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.3 "
                           "--set run.output_interval=0.1 --set tank.max=[1.6,1.2,0.8] --set fluid.0.max=[0.4,1.2,0.6] "
                           "--export-fields velocity,density --export ";
  check_2_ranks_follow(args, "wide", 4, 1e-3 * spacing);
}

TEST_CASE("a run resumes from its export's last frame, on one rank or several", "[dist][mpi]") {
  const double spacing = 0.04;
  const std::string base = source_path("scenes/dam_break.json") +
                           " --backend cpu --quiet --set sph.spacing=0.04 --set run.output_interval=0.1 "
                           "--export-fields velocity,density ";
  const std::string first = tmp_dir() + "/first.h5", whole = tmp_dir() + "/whole.h5";
  REQUIRE(run_ranks(1, base + "--set run.end_time=0.2 --export " + first).code == 0);
  REQUIRE(run_ranks(1, base + "--set run.end_time=0.5 --export " + whole).code == 0);
  const Frame end = FrameReader(whole).read(5);
  REQUIRE(end.time == Approx(0.5));
  for (int ranks : {1, 2}) {
    const std::string out = tmp_dir() + "/resumed" + std::to_string(ranks) + ".h5";
    const CliResult r = run_ranks(ranks, base + "--set run.end_time=0.5 --resume " + first + " --export " + out);
    INFO(ranks << " ranks: " << r.output);
    REQUIRE(r.code == 0);
    CHECK(has(r.output, "resumed from " + first + " at t = 0.2 s (step 200, 1120 particles)"));
    CHECK(has(r.output, "simulated      0.3 s in 300 steps"));  // this run's share
    const FrameReader got(out);
    REQUIRE(got.frames().size() == 4);  // t = 0.2 (the frame resumed from), 0.3, 0.4, 0.5
    const Frame last = got.read(3);
    CHECK(last.time == Approx(0.5));
    CHECK(last.step == end.step);
    // Not bit for bit: the export holds v, not the predicted velocity u the
    // neighbours read in the first step (integrate.h), which starts as v.
    // Measured: 3.5e-5 m at most (9e-4 spacings) 0.3 s later.
    CHECK(largest_offset(end, last) <= 1e-2 * spacing);
  }
  SECTION("an export without velocity is refused") {
    const std::string bare = tmp_dir() + "/bare.h5";
    REQUIRE(run_ranks(1, source_path("scenes/dam_break.json") + " --backend cpu --quiet --set sph.spacing=0.04 "
                             "--set run.end_time=0.1 --export " + bare).code == 0);
    const CliResult r = run_ranks(1, source_path("scenes/dam_break.json") + " --backend cpu --quiet --set "
                                         "sph.spacing=0.04 --set run.end_time=0.3 --resume " + bare);
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(has(r.output, "--resume: the frame has no velocity or density"));
  }
  SECTION("an export of another spacing is refused") {
    const CliResult r = run_ranks(1, source_path("scenes/dam_break.json") +
                                         " --backend cpu --quiet --set sph.spacing=0.05 --resume " + first);
    INFO(r.output);
    CHECK(r.code == 2);
    CHECK(has(r.output, "exported from another scene or spacing"));
  }
}

TEST_CASE("mesh obstacles over 2 ranks: every solver follows its one-rank run", "[dist][mpi]") {
  // Every rank holds all the obstacles' wall particles; WCSPH's ghosts near
  // them are two supports wide (their pressure sums), PBF's and DFSPH's one.
  // Measured (3 cm, 2,860 particles, slabs along y; DFSPH at tolerances of
  // 1e-5, as above) at 0.05 and 0.1 s: WCSPH 6e-8 and 1.5e-7 m, PBF 3.2e-6
  // and 5.5e-4 m (its round-off grows fastest: 6e-8 m at 0.01 s, about
  // doubling every 0.01 s, with a step at 0.07 s where an ulp decides a
  // correction), DFSPH 1e-6 and 4e-6 m. A lost or doubled neighbour moves a
  // particle by a good part of a spacing.
  const double spacing = 0.03;
  for (const auto& [solver, bound] : std::vector<std::pair<std::string, double>>{
           {"wcsph", 1e-4}, {"pbf", 0.05}, {"dfsph --set dfsph.tolerance=1e-5 --set dfsph.divergence_tolerance=1e-5", 1e-3}}) {
    INFO(solver);
    const std::string args = source_path("scenes/dam_break_obstacles.json") +
                             " --backend cpu --quiet --set sph.spacing=0.03 --set run.end_time=0.1 "
                             "--set run.output_interval=0.05 --export-fields velocity,density --set sph.solver=" +
                             solver + " --export ";
    check_2_ranks_follow(args, "obstacles", 3, bound * spacing);
  }
}

TEST_CASE("PBF over 2 ranks with vorticity confinement and a density tolerance follows one rank", "[dist][mpi]") {
  // The confinement's two passes read the neighbours' velocities and
  // vorticities (refreshed for the ghosts), and the tolerance's early end is
  // decided on the error summed over the ranks: the same iterations on both
  // (every step after the first counts as flowing, pbf.flow_speed 0, so
  // that the tolerance may end its iterations).
  const double spacing = 0.04;
  const std::string args = source_path("scenes/dam_break.json") +
                           " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.1 "
                           "--set run.output_interval=0.05 --set sph.solver=pbf --set pbf.vorticity=0.5 "
                           "--set pbf.tolerance=0.002 --set pbf.flow_speed=0 --export-fields velocity,density --export ";
  check_2_ranks_follow(args, "vorticity", 3, 1e-4 * spacing);
}

TEST_CASE("PBF's passes beside the ghost refresh give the run of the passes before it, bit for bit", "[dist][mpi]") {
  // --overlap on: each pass skips the ghosts and computes first the
  // particles whose values the peers read, which travel while the rest of
  // the pass runs; off: the whole pass, then the refresh. The ghosts' own
  // results were what the refresh overwrote, and each owned particle sums
  // the same neighbours in the same order: the same run. Three ranks (one
  // with ghosts on both sides), and the obstacles' scene on two (its stop
  // pass runs before the refresh).
  struct Case {
    const char* scene;
    const char* spacing;
    int ranks;
  };
  for (const Case c : {Case{"scenes/dam_break.json", "0.04", 3}, Case{"scenes/dam_break_obstacles.json", "0.03", 2}}) {
    INFO(c.scene);
    const std::string args = source_path(c.scene) + " --backend cpu --quiet --set sph.solver=pbf --set sph.spacing=" +
                             c.spacing + " --set run.end_time=0.2 --set run.output_interval=0.1 "
                             "--export-fields velocity,density --export ";
    const std::string on = tmp_dir() + "/overlap_on.h5", off = tmp_dir() + "/overlap_off.h5";
    const CliResult a = run_ranks(c.ranks, "--overlap on " + args + on);
    const CliResult b = run_ranks(c.ranks, "--overlap off " + args + off);
    INFO(a.output << b.output);
    REQUIRE(a.code == 0);
    REQUIRE(b.code == 0);
    const FrameReader fa(on), fb(off);
    REQUIRE(fa.frames().size() == 3);
    REQUIRE(fb.frames().size() == 3);
    for (size_t k = 0; k < 3; ++k) {
      const Frame x = fa.read(k), y = fb.read(k);
      INFO("frame " << k);
      CHECK(x.step == y.step);
      CHECK(largest_offset(x, y) == 0.0);
      CHECK(x.velocity == y.velocity);
    }
  }
  const CliResult bad = run_ranks(1, "--overlap sometimes " + source_path("scenes/dam_break.json") + " --backend cpu");
  INFO(bad.output);
  CHECK(bad.code == 2);
  CHECK(has(bad.output, "--overlap"));
  check_refused_on_2_ranks("--overlap on " + source_path("scenes/dam_break.json") + " --backend cpu --quiet",
                           "--overlap on: only PBF's ghost refresh runs beside its passes; this scene runs wcsph");
}

TEST_CASE("PBF and DFSPH resume from an export on one rank or several", "[dist][mpi]") {
  const double spacing = 0.04;
  for (const std::string solver : {"pbf", "dfsph"}) {
    INFO(solver);
    const std::string base = source_path("scenes/dam_break.json") + " --backend cpu --quiet --set sph.spacing=0.04 "
                             "--set run.output_interval=0.1 --export-fields velocity,density --set sph.solver=" +
                             solver + " ";
    const std::string first = tmp_dir() + "/" + solver + "_first.h5", whole = tmp_dir() + "/" + solver + "_whole.h5";
    REQUIRE(run_ranks(1, base + "--set run.end_time=0.2 --export " + first).code == 0);
    REQUIRE(run_ranks(1, base + "--set run.end_time=0.5 --export " + whole).code == 0);
    const Frame end = FrameReader(whole).read(5);
    for (int ranks : {1, 2}) {
      const std::string out = tmp_dir() + "/" + solver + "_resumed" + std::to_string(ranks) + ".h5";
      const CliResult r = run_ranks(ranks, base + "--set run.end_time=0.5 --resume " + first + " --export " + out);
      INFO(ranks << " ranks: " << r.output);
      REQUIRE(r.code == 0);
      const Frame last = FrameReader(out).read(3);
      CHECK(last.time == Approx(0.5));
      CHECK(last.step == end.step);
      // Every particle, under its own id (largest_offset compares the ids).
      // Not bit for bit: the export lacks DFSPH's warm-start pressures and
      // PBF's step control, and these flows grow a small difference fast
      // (the ranks' round-off: "PBF on 2 and 3 ranks ..."). Measured 0.3 s
      // later: PBF 1.2e-3 m on 1 rank, 6.2e-3 m on 2; DFSPH 2.4e-3 m on both.
      CHECK(largest_offset(end, last) <= 0.3 * spacing);
    }
  }
}

namespace {

// Two exports of the same run hold the same frames: every dataset and
// attribute alike, bit for bit, and the same walls.
void check_same_export(const std::string& a_path, const std::string& b_path) {
  const FrameReader a(a_path), b(b_path);
  CHECK(b.header().boundary == a.header().boundary);
  REQUIRE(b.frames().size() == a.frames().size());
  for (size_t k = 0; k < a.frames().size(); ++k) {
    INFO("frame " << k);
    CHECK(b.frames()[k].datasets == a.frames()[k].datasets);
    const Frame fa = a.read(k), fb = b.read(k);
    CHECK(fb.time == fa.time);
    CHECK(fb.dt == fa.dt);
    CHECK(fb.step == fa.step);
    CHECK(fb.id == fa.id);
    CHECK(fb.position == fa.position);
    CHECK(fb.velocity == fa.velocity);
    CHECK(fb.density == fa.density);
    CHECK(fb.pressure == fa.pressure);
    CHECK(std::is_sorted(fb.id.begin(), fb.id.end()));
    CHECK(std::adjacent_find(fb.id.begin(), fb.id.end()) == fb.id.end());
  }
  // The sidecars differ only in the file they name.
  auto sidecar = [](const std::string& h5) {
    std::string text = slurp(xdmf_path(h5));
    const std::string name = h5.substr(h5.rfind('/') + 1);
    for (size_t at; (at = text.find(name)) != std::string::npos;) text.replace(at, name.size(), "EXPORT");
    return text;
  };
  CHECK(sidecar(b_path) == sidecar(a_path));
}

}  // namespace

TEST_CASE("an export written by every rank holds what rank 0 writes of the same run", "[dist][mpi]") {
  const std::string base = source_path("scenes/dam_break.json") +
                           " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.3 "
                           "--set run.output_interval=0.1 --export-fields velocity,density,pressure ";
  if (!parallel_hdf5_built()) {
    check_refused_on_2_ranks(base + "--set export.writer=parallel --export " + tmp_dir() + "/p.h5",
                             "export.writer \"parallel\": this sphray was built without parallel HDF5");
    return;
  }
  // Each SECTION runs the test case from the top: the runs of each are inside it.
  SECTION("the dam break on 2 and 3 ranks") {
    for (int ranks : {2, 3}) {
      const std::string tag = tmp_dir() + "/writers" + std::to_string(ranks);
      const CliResult root = run_ranks(ranks, base + "--set export.writer=rank0 --export " + tag + "_rank0.h5");
      const CliResult all = run_ranks(ranks, base + "--set export.writer=parallel --export " + tag + "_ranks.h5");
      INFO(ranks << " ranks: " << root.output << all.output);
      REQUIRE(root.code == 0);
      REQUIRE(all.code == 0);
      CHECK(has(all.output, "4 frames to " + tag + "_ranks.h5 (XDMF sidecar for ParaView next to it); every rank "
                            "wrote its rows (parallel HDF5)"));
      CHECK(has(root.output, "the run waited"));
      check_same_export(tag + "_rank0.h5", tag + "_ranks.h5");
    }
    // A run resumes from the export every rank wrote (contiguous datasets).
    const std::string from = tmp_dir() + "/writers2_ranks.h5", resumed = tmp_dir() + "/writers_resumed.h5";
    const CliResult r = run_ranks(1, source_path("scenes/dam_break.json") +
                                         " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.4 "
                                         "--set run.output_interval=0.1 --export-fields velocity,density --resume " +
                                         from + " --export " + resumed);
    INFO(r.output);
    REQUIRE(r.code == 0);
    CHECK(has(r.output, "resumed from " + from + " at t = 0.3 s"));
    const Frame last = FrameReader(from).read(3), first = FrameReader(resumed).read(0);
    CHECK(first.id == last.id);
    CHECK(first.position == last.position);
    CHECK(first.velocity == last.velocity);
  }
  SECTION("particles gone through an open top leave gaps in the ids: the rows close them alike") {
    const std::string scene = tmp_dir() + "/gaps.json";
    std::ofstream(scene) << R"({"tank": {"min": [0,0,0], "max": [0.2,0.1,0.1], "open_top": true},
      "fluid": [{"min": [0.12,0.04,0.02], "max": [0.16,0.06,0.04], "velocity": [0,0,20]},
                {"min": [0.02,0.02,0.0], "max": [0.08,0.08,0.04]}],
      "sph": {"spacing": 0.01}, "run": {"end_time": 0.03, "output_interval": 0.01}})";
    const std::string args = scene + " --backend cpu --quiet --export-fields velocity,density --export " + tmp_dir();
    const CliResult root = run_ranks(2, args + "/gaps_rank0.h5 --set export.writer=rank0");
    const CliResult all = run_ranks(2, args + "/gaps_ranks.h5 --set export.writer=parallel");
    INFO(root.output << all.output);
    REQUIRE(root.code == 0);
    REQUIRE(all.code == 0);
    check_same_export(tmp_dir() + "/gaps_rank0.h5", tmp_dir() + "/gaps_ranks.h5");
    const FrameReader r(tmp_dir() + "/gaps_ranks.h5");
    const Frame last = r.read(r.frames().size() - 1), first = r.read(0);
    CHECK(last.count() < first.count());  // the jet has left
    CHECK(last.id.front() > 0);           // its ids were the first
  }
  SECTION("what every rank cannot write goes through rank 0, or is refused when asked for by name") {
    const std::string field = source_path("scenes/dam_break.json") +
                              " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.1 "
                              "--export-fields velocity,field --export " + tmp_dir() + "/f.h5";
    const CliResult automatic = run_ranks(2, field);
    INFO(automatic.output);
    CHECK(automatic.code == 0);
    CHECK(has(automatic.output, "the run waited"));  // rank 0's writer
    check_refused_on_2_ranks(field + " --set export.writer=parallel",
                             "export.writer \"parallel\": --export-fields field is built on rank 0 alone");
    check_refused_on_2_ranks(base + "--set export.gzip=4 --set export.writer=parallel --export " + tmp_dir() + "/g.h5",
                             "export.gzip compresses on rank 0 alone");
    check_refused_on_2_ranks(base + "--set export.writer=all --export " + tmp_dir() + "/u.h5", "export.writer");
  }
}

TEST_CASE("a particle that outruns c0 on one rank is named by that rank, not by the first", "[dist][mpi]") {
  // Two blocks of 4^3 particles at either end of the tank, the far one thrown
  // down at 1.9 m/s: it outruns c0 = 2 m/s after about 0.01 s, and every rank
  // stops (the largest speed is every rank's). The still block lies on rank 0,
  // which reports first and would name one of its own particles in both
  // layouts. The thrown block's ids follow the other's (0-63) or come first.
  const std::string path = tmp_dir() + "/two_blocks.json";
  for (const bool thrown_first : {false, true}) {
    const std::string still = R"({"min": [0.05,0.03,0.2], "max": [0.09,0.07,0.24]})";
    const std::string thrown = R"({"min": [0.51,0.03,0.2], "max": [0.55,0.07,0.24], "velocity": [0,0,-1.9]})";
    std::ofstream(path) << R"({"tank": {"min": [0,0,0], "max": [0.6,0.1,0.4]}, "fluid": [)"
                        << (thrown_first ? thrown + "," + still : still + "," + thrown)
                        << R"(], "sph": {"spacing": 0.01, "speed_of_sound": 2}, "run": {"end_time": 0.05}})";
    const CliResult r = run_ranks(2, path + " --backend cpu --quiet");
    INFO(r.output);
    CHECK(r.code == 1);
    const size_t at = r.output.find("faster than the speed of sound");
    REQUIRE(at != std::string::npos);
    const size_t p = r.output.rfind("particle ", at);
    REQUIRE(p != std::string::npos);
    const int id = std::stoi(r.output.substr(p + 9));
    if (thrown_first) CHECK(id < 64);
    else CHECK(id >= 64);
  }
}

TEST_CASE("a rank that dies ends the run with its rank named, and the frames written stay readable", "[dist][mpi]") {
  // Both writers of the export: rank 0's, and every rank's where this build has parallel HDF5.
  for (const std::string writer : {"rank0", "auto"}) {
    const std::string out = tmp_dir() + "/killed_" + writer + ".h5", log = tmp_dir() + "/killed.txt",
                      csv = tmp_dir() + "/killed.csv";
    std::filesystem::remove(csv);
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    setenv("OMP_NUM_THREADS", "1", 1);
    // A run far longer than the test, one of whose ranks is killed (the newest
    // process of the command line) once five frames are out (the metrics CSV,
    // a row per frame, flushed); `timeout` turns a hang into exit code 124.
    const std::string marker = "--set run.end_time=29.5";
    const std::string cmd = "timeout 120 " + std::string(SPHRAY_MPIEXEC) + " -n 2 " + SPHRAY_EXE + " run " +
                            source_path("scenes/dam_break.json") +
                            " --backend cpu --quiet --set sph.spacing=0.04 --set run.output_interval=0.02 " + marker +
                            " --set export.writer=" + writer + " --metrics-csv " + csv + " --export " + out + " > " +
                            log + " 2>&1 & pid=$!; "
                            "for i in $(seq 300); do sleep 0.2; [ $(cat " + csv +
                            " 2>/dev/null | wc -l) -gt 5 ] && break; done; "
                            "pkill -9 -n -f -- '" + marker + "'; wait $pid";
    const std::string script = tmp_dir() + "/kill_a_rank.sh";
    std::ofstream(script) << cmd << "\n";
    const int status = std::system(("bash " + script).c_str());
    const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    const std::string text = slurp(log);
    INFO(writer << ": exit " << code << ": " << text);
    CHECK(code != 0);
    CHECK(code != 124);  // ended, not timed out
    CHECK((has(text, "process rank 0") || has(text, "process rank 1")));
    CHECK(has(text, "signal 9"));
    const FrameReader reader(out);
    REQUIRE(reader.frames().size() >= 2);
    const Frame f = reader.read(reader.frames().size() - 1);
    CHECK(f.count() == 1120);
  }
}

TEST_CASE("PNG frames of a run over several ranks are rank 0's renders of all particles", "[dist][mpi]") {
  // The naive builder: the presence builder's field differs by whether the
  // step computed presence, which a run over several ranks does not.
  const std::string base = source_path("scenes/dam_break.json") +
                           " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.2 "
                           "--set run.output_interval=0.1 --set field.builder=naive --size 160x90 --frames-dir ";
  const std::string one = tmp_dir() + "/png1", two = tmp_dir() + "/png2";
  CHECK(has(run_on_1_and_2(base, one, two), "3 PNGs"));
  for (int k = 0; k < 3; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "/frame_%06d.png", k);
    const Image a = read_png(one + name), b = read_png(two + name);
    // The same particles to round-off (the 2-rank test above): the same image
    // but for pixels where a surface passes a voxel's edge.
    CHECK(psnr(a, b) > 40.0);
  }
}

TEST_CASE("more ranks than the domain holds are refused before the run", "[dist][mpi]") {
  const CliResult r = run_ranks(6, source_path("scenes/dam_break.json") +
                                       " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.01");
  INFO(r.output);
  CHECK(r.code == 2);
  CHECK(has(r.output, "6 ranks need slabs at least 0.32 m thick"));
  CHECK(has(r.output, "at most 5 ranks"));
  // An axis asked for that cannot hold them.
  check_refused_on_2_ranks(source_path("scenes/dam_break.json") +
                               " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.01 --cut-axis z",
                           "along z, which is 0.6 m long: at most 1 ranks");
}

TEST_CASE("a scene too large for a rank's memory is refused before the particles are made, naming the rank",
          "[dist][mpi]") {
  // 640M particles: about 150 GiB for each of 2 ranks, checked before either builds the lattice.
  const CliResult r = run_ranks(2, source_path("scenes/dam_break.json") +
                                       " --backend cpu --quiet --set sph.spacing=0.0005 --set run.end_time=0.01");
  INFO(r.output);
  CHECK(r.code == 2);
  CHECK(has(r.output, " GiB on rank "));
  CHECK(has(r.output, " of 2 ("));
  CHECK(has(r.output, "fluid particles (an even share)"));
  CHECK(has(r.output, "its share of the node's, with 2 ranks on it"));
  CHECK(has(r.output, "or run on more ranks"));
}

TEST_CASE("sphray view over 2 ranks shows what one rank shows", "[dist][mpi]") {
  if (!SPHRAY_TEST_VIEWER || std::system("command -v xvfb-run > /dev/null 2>&1") != 0) {
    WARN("no viewer in this build, or no xvfb-run: not tested");
    return;
  }
  setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  setenv("OMPI_MCA_rmaps_base_oversubscribe", "1", 1);
  setenv("OMP_NUM_THREADS", "1", 1);
  // Fixed substeps (real-time playback steps by the wall clock): both runs
  // take the same 12 steps; rank 0 draws the particles it gathered. WCSPH
  // (the built-in scene runs PBF, whose 2-rank run differs in round-off:
  // 419 of 129,600 pixels by more than 20, PSNR 41.6 dB).
  auto view = [&](int ranks, const std::string& png) {
    const std::string log = tmp_dir() + "/view_ranks.log";
    const std::string cmd = "xvfb-run -a -s '-screen 0 1024x768x24' " + std::string(SPHRAY_MPIEXEC) + " -n " +
                            std::to_string(ranks) + " " + SPHRAY_EXE +
                            " view --backend cpu --frames 6 --substeps 2 --size 480x270 --set sph.solver=wcsph --screenshot " + png + " > " +
                            log + " 2>&1";
    const int status = std::system(cmd.c_str());
    INFO(slurp(log));
    REQUIRE(WIFEXITED(status));
    REQUIRE(WEXITSTATUS(status) == 0);
    return slurp(log);
  };
  const std::string one = tmp_dir() + "/view_1.png", two = tmp_dir() + "/view_2.png";
  view(1, one);
  CHECK(has(view(2, two), "viewer: 2 ranks"));
  const Image a = read_png(one), b = read_png(two);
  REQUIRE(a.rgba.size() == b.rgba.size());
  // The same particles (identical here: measured 0 pixels): any pixel that
  // differs is the viewer's.
  CHECK(pixels_differing(a, b, 20) < a.rgba.size() / 1000);
}

TEST_CASE("what a run over several ranks cannot do yet is refused by name", "[dist][mpi]") {
  const std::string base =
      source_path("scenes/dam_break.json") + " --backend cpu --quiet --set sph.spacing=0.04 --set run.end_time=0.01 ";
  check_refused_on_2_ranks("sim --backend cpu --sizes 8k",
                           "only 'sphray run' and 'sphray view' run over several ranks (started as one of 2)", "bench");
  check_refused_on_2_ranks(base + "--export " + tmp_dir() + "/p.h5 --export-fields presence",
                           "--export-fields presence is not available in a run over several ranks");
  check_refused_on_2_ranks(base + "--set sph.solver=dfsph --export " + tmp_dir() + "/p.h5 --export-fields pressure",
                           "--export-fields pressure under dfsph is not available in a run over several ranks");
}
#endif
