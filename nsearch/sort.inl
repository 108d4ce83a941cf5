// The grid sort, written once for both backends: cell keys, a stable sort by
// key, and the slab and cell tables (grid.h). Included inside a backend
// namespace (which supplies Vector, raw, policy, sort_pairs, parallel_for),
// after grid.h.

SPHRAY_HD SPHRAY_FORCEINLINE Vec3f position_of(const Float4& p) { return xyz(p); }
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f position_of(const Vec3f& p) { return p; }

// Cell key of every point (particles as Float4, plain points as Vec3f).
template <class P>
struct KeyOf {
  GridGeom grid;
  const P* pts;
  uint32_t* keys;
  SPHRAY_HD void operator()(uint32_t i) const { keys[i] = grid.fine_key_of(position_of(pts[i])); }
};

// Coarse cell table from the slab table (grid.h): offsets[c] = fine[c * kSubX].
struct CoarseOffsets {
  const uint32_t* fine;
  uint32_t* coarse;
  SPHRAY_HD void operator()(uint32_t c) const { coarse[c] = fine[c * uint32_t(GridGeom::kSubX)]; }
};

// Sorts `n` fine keys with their order (stable, so both backends agree on the
// order within a slab; on the key bits in use) and fills fine[k] = first
// sorted index with key >= k, for k in [0, num_fine_cells]: one vectorised
// binary search per slab, parallel over slabs (a scatter of the slab starts
// and a min-scan from the right gives the same table no faster, in three
// kernels). Then the coarse table, when one is asked for.
inline void sort_and_offsets(const GridGeom& g, uint32_t n, Vector<uint32_t>& keys, Vector<uint32_t>& order,
                             Vector<uint32_t>& fine, Vector<uint32_t>* coarse) {
  thrust::sequence(policy(), order.begin(), order.begin() + n);
  int bits = 1;  // the keys run up to num_fine_cells() (outside the grid)
  while (bits < 32 && (g.num_fine_cells() >> bits) != 0) ++bits;
  sort_pairs(keys, order, n, bits);
  thrust::lower_bound(policy(), keys.begin(), keys.begin() + n, thrust::counting_iterator<uint32_t>(0),
                      thrust::counting_iterator<uint32_t>(g.num_fine_cells() + 1), fine.begin());
  if (coarse) parallel_for("coarse_offsets", g.num_cells() + 1, CoarseOffsets{raw(fine), raw(*coarse)});
}

