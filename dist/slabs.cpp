#include "slabs.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace sphray {

int SlabPlan::owner(double x) const {
  return int(std::upper_bound(cuts.begin(), cuts.end(), x) - cuts.begin());
}

SlabBounds slab_bounds(const SlabPlan& p, int rank) {
  SlabBounds b;
  b.axis = p.axis;
  b.halo = float(p.halo);
  b.halo_free = float(p.halo_free);
  const float inf = std::numeric_limits<float>::infinity();
  for (int k = 0; k < kPeers; ++k) {
    const int r = rank + k - kSelf;
    b.exists[k] = r >= 0 && r < p.ranks();
    if (!b.exists[k]) continue;
    b.lo[k] = r == 0 ? -inf : float(p.slab_lo(r));
    b.hi[k] = r == p.ranks() - 1 ? inf : float(p.slab_hi(r));
  }
  return b;
}

AxisHistogram AxisHistogram::over(double lo, double hi, double width) {
  AxisHistogram h;
  h.lo = lo;
  h.width = width;
  h.counts.assign(size_t(std::max(1.0, std::ceil((hi - lo) / width))), 0.0);
  return h;
}

void AxisHistogram::add(double x) { counts[axis_bin(x, lo, width, uint32_t(counts.size()))] += 1.0; }

const char* axis_name(int axis) { return axis == 0 ? "x" : axis == 1 ? "y" : "z"; }

void check_rank_count(int ranks, double lo, double hi, double min_width, const std::string& along) {
  if (ranks < 1) throw std::invalid_argument("a decomposed run needs at least one rank");
  const double length = hi - lo;
  if (ranks == 1 || length >= ranks * min_width * (1.0 - 1e-9)) return;
  std::ostringstream os;
  os << ranks << " ranks need slabs at least " << min_width << " m thick (two support radii, the halo), "
     << ranks * min_width << " m along " << along << ", which is " << length
     << " m long: at most " << std::max(1, int(std::floor(length / min_width + 1e-9))) << " ranks";
  throw std::invalid_argument(os.str());
}

std::vector<double> balanced_cuts(const AxisHistogram& h, int ranks, double lo, double hi, double min_width) {
  std::vector<double> cuts(size_t(std::max(0, ranks - 1)), 0.0);
  double total = 0;
  for (double c : h.counts) total += c;
  // The k-th cut where the running count passes k / ranks of the total,
  // interpolated within the bin.
  double below = 0;
  size_t bin = 0;
  for (int k = 1; k < ranks; ++k) {
    const double target = total * k / ranks;
    while (bin < h.counts.size() && below + h.counts[bin] < target) below += h.counts[bin++];
    double x = hi;
    if (bin < h.counts.size()) {
      const double in_bin = h.counts[bin] > 0 ? (target - below) / h.counts[bin] : 0.0;
      x = h.lo + (double(bin) + in_bin) * h.width;
    }
    cuts[size_t(k) - 1] = x;
  }
  // At least min_width apart and from the ends: up from the left, then down
  // from the right (feasible when the domain holds ranks * min_width).
  double prev = lo;
  for (double& c : cuts) prev = c = std::max(c, prev + min_width);
  double next = hi;
  for (auto it = cuts.rbegin(); it != cuts.rend(); ++it) next = *it = std::min(*it, next - min_width);
  return cuts;
}

double most_held(const AxisHistogram& h, const std::vector<double>& cuts, double halo) {
  // below(x): the particles below x, by the running sum of the bins.
  std::vector<double> sum(h.counts.size() + 1, 0.0);
  for (size_t b = 0; b < h.counts.size(); ++b) sum[b + 1] = sum[b] + h.counts[b];
  auto below = [&](double x) {
    const double at = (x - h.lo) / h.width;
    if (at <= 0) return 0.0;
    if (at >= double(h.counts.size())) return sum.back();
    const size_t b = size_t(at);
    return sum[b] + (at - double(b)) * h.counts[b];
  };
  const double inf = std::numeric_limits<double>::infinity();
  double most = 0;
  for (size_t r = 0; r <= cuts.size(); ++r) {
    const double a = r == 0 ? -inf : cuts[r - 1] - halo, e = r == cuts.size() ? inf : cuts[r] + halo;
    most = std::max(most, below(e) - below(a));
  }
  return most;
}

double imbalance(const std::vector<double>& counts) {
  if (counts.empty()) return 0;
  double sum = 0, most = 0;
  for (double c : counts) sum += c, most = std::max(most, c);
  const double mean = sum / double(counts.size());
  return mean > 0 ? most / mean - 1.0 : 0.0;
}

}  // namespace sphray
