// The cut of a decomposed run's domain into slabs, one per rank, along one
// axis: a cut plane that only ever needs one coordinate to find a particle's
// owner. Slabs are at least `min_width` thick (the halo, so that a rank's
// ghosts come from ranks whose slabs touch its own, and a particle crosses at
// most one cut per step); the cuts sit at the quantiles of the particles along
// the axis, so the ranks own about equal counts. The axis is the one whose
// cuts leave the busiest rank the fewest particles, its own and its ghosts
// (most_held): every rank waits for the slowest at each step's reductions,
// and a rank's step costs about its particle count. Cuts across the liquid's
// smallest section make the fewest ghosts: the dam break's column, 0.4 m
// along x and 0.67 m along y, is cut along y, and since its flow runs along
// x, its slabs keep their particles as it collapses.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "sph/exchange.h"

namespace sphray {

struct SlabPlan {
  int axis = 0;             // 0 x, 1 y, 2 z
  // most_held along each axis at the start (halo_free wide); 0 where the axis
  // cannot hold the ranks' slabs.
  double held[3] = {0, 0, 0};
  double lo = 0, hi = 0;    // the domain along the axis [m]
  double halo = 0;          // ghost width [m] near wall particles: particles within it of a slab are copied to its rank
  double halo_free = 0;     // ghost width [m] elsewhere
  double bin = 0;           // [m] the bins of the particle histogram the cuts are placed by
  double min_width = 0;     // [m]
  std::vector<double> cuts; // the ranks - 1 interior cuts, ascending

  int ranks() const { return int(cuts.size()) + 1; }
  // The rank owning coordinate x (along the axis): slab r is [cut r-1, cut r);
  // outside the domain, the first or last.
  int owner(double x) const;
  double slab_lo(int r) const { return r == 0 ? lo : cuts[size_t(r) - 1]; }
  double slab_hi(int r) const { return r == ranks() - 1 ? hi : cuts[size_t(r)]; }
};

// The slabs of ranks rank - 2 .. rank + 2 as the solver's exchange reads them
// (sph/exchange.h).
SlabBounds slab_bounds(const SlabPlan& p, int rank);

// Particle counts along the axis in bins of `width` over [lo, hi]: what the cuts
// are placed by (summed over the ranks for a rebalance).
struct AxisHistogram {
  double lo = 0, width = 1;
  std::vector<double> counts;
  static AxisHistogram over(double lo, double hi, double width);
  void add(double x);
};

// A domain too short for `ranks` slabs of `min_width` along the axis named
// `along` (std::invalid_argument with the numbers: the most ranks it holds).
void check_rank_count(int ranks, double lo, double hi, double min_width, const std::string& along);

// The cuts at the quantiles k / ranks of the histogram's counts, pushed apart
// to min_width (and inside [lo, hi]).
std::vector<double> balanced_cuts(const AxisHistogram& h, int ranks, double lo, double hi, double min_width);

// The most particles one rank holds with slabs cut at `cuts`: those of the
// histogram in its slab widened by `halo` on each side (its own and its
// ghosts), a bin's particles taken as spread evenly across it.
double most_held(const AxisHistogram& h, const std::vector<double>& cuts, double halo);

// Largest count over the mean count, minus one (0: balanced).
double imbalance(const std::vector<double>& counts);

const char* axis_name(int axis);

}  // namespace sphray
