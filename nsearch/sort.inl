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

// fine[keys[i]] = i where sorted slab keys[i] starts (sort_and_offsets).
struct SlabStarts {
  const uint32_t* keys;
  uint32_t* fine;
  SPHRAY_HD void operator()(uint32_t i) const {
    if (i == 0 || keys[i] != keys[i - 1]) fine[keys[i]] = i;
  }
};

// Sorts `n` fine keys with their order (stable, so both backends agree on the
// order within a slab; on the key bits in use) and fills fine[k] = first
// sorted index with key >= k, for k in [0, num_fine_cells]: n everywhere, the
// start of each occupied slab scattered, and a min-scan from the right
// carrying each start down over the empty slabs before it. (A vectorised
// binary search per slab costs log2(n) dependent loads per slab: 0.07 ms
// more at 1M particles on the 3.7M slabs of PBF's step grid, H100.) Then
// the coarse table, when one is asked for.
inline void sort_and_offsets(const GridGeom& g, uint32_t n, Vector<uint32_t>& keys, Vector<uint32_t>& order,
                             Vector<uint32_t>& fine, Vector<uint32_t>* coarse) {
  thrust::sequence(policy(), order.begin(), order.begin() + n);
  int bits = 1;  // the keys run up to num_fine_cells() (outside the grid)
  while (bits < 32 && (g.num_fine_cells() >> bits) != 0) ++bits;
  sort_pairs(keys, order, n, bits);
  const uint32_t slabs = g.num_fine_cells();
  thrust::fill_n(policy(), fine.begin(), slabs + 1, n);
  parallel_for("slab_starts", n, SlabStarts{raw(keys), raw(fine)});
  const auto last = thrust::make_reverse_iterator(fine.begin() + slabs + 1);
  thrust::inclusive_scan(policy(), last, thrust::make_reverse_iterator(fine.begin()), last, thrust::minimum<uint32_t>());
  if (coarse) parallel_for("coarse_offsets", g.num_cells() + 1, CoarseOffsets{raw(fine), raw(*coarse)});
}

