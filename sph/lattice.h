// The neighbours of a node in a cubic lattice: the sums over a full lattice
// that set the solvers' constants (the particle volume, the presence lobe,
// PBF's relaxation scale and its spectrum bound).
#pragma once

#include <cmath>

namespace sphray {

// Calls f(x, y, z, r) for every other node (x, y, z) dx of a cubic lattice
// of spacing dx within `support` of a node, r its distance.
template <class F>
void for_lattice_neighbours(double support, double dx, F&& f) {
  const int m = int(std::ceil(support / dx));
  for (int z = -m; z <= m; ++z)
    for (int y = -m; y <= m; ++y)
      for (int x = -m; x <= m; ++x) {
        const double r = dx * std::sqrt(double(x * x + y * y + z * z));
        if ((x || y || z) && r < support) f(x, y, z, r);
      }
}

}  // namespace sphray
