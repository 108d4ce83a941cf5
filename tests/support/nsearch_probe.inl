// The probes of nsearch_probe.h written once for both backends. Included
// inside a backend namespace, after nsearch/sort.inl.

// Sorted keys back to coarse cell keys (for GridBuild).
struct CoarseKey {
  SPHRAY_HD uint32_t operator()(uint32_t k) const { return k / uint32_t(GridGeom::kSubX); }
};

inline GridBuild build_grid_impl(const GridGeom& g, const std::vector<Vec3f>& points) {
  const uint32_t n = uint32_t(points.size());
  Vector<Vec3f> pts;
  upload(pts, points);
  Vector<uint32_t> keys(n), order(n), offsets(size_t(g.num_cells()) + 1), fine(size_t(g.num_fine_cells()) + 1);
  parallel_for("probe_keys", n, KeyOf<Vec3f>{g, raw(pts), raw(keys)});
  sort_and_offsets(g, n, keys, order, fine, &offsets);
  thrust::transform(policy(), keys.begin(), keys.begin() + n, keys.begin(), CoarseKey());
  return {download(order, n), download(keys, n), download(offsets, offsets.size()), download(fine, fine.size())};
}

inline PairMaskBuild build_pair_masks_impl(const GridGeom& g, const std::vector<Vec3f>& points, float radius,
                                           uint32_t capacity, const std::vector<Vec3f>* queries,
                                           bool tensor_tiles = true) {
  PairMaskBuild out;
  out.grid = build_grid_impl(g, points);
  const uint32_t n = out.grid.offsets.back();  // points inside the grid, sorted first
  std::vector<Float4> sorted(n);
  for (uint32_t k = 0; k < n; ++k) {
    const Vec3f p = points[out.grid.order[k]];
    sorted[k] = {p.x, p.y, p.z, 0.0f};
  }
  // The queries: the sorted points themselves, or the given ones.
  std::vector<Float4> query_pts = sorted;
  if (queries) {
    query_pts.resize(queries->size());
    for (size_t k = 0; k < queries->size(); ++k) query_pts[k] = {(*queries)[k].x, (*queries)[k].y, (*queries)[k].z, 0.0f};
  }
  const uint32_t nq = uint32_t(query_pts.size());
  Vector<Float4> pts, qpts;
  Vector<uint32_t> fine;
  Vector<uint8_t> near;
  upload(pts, sorted);
  upload(qpts, query_pts);
  upload(fine, out.grid.fine_offsets);
  if (queries) {
    near.resize(g.num_cells());
    parallel_for("probe_cells_near", g.num_cells(), CellsNear{g, raw(fine), raw(near)});
  }
  Vector<PairWord> words(size_t(capacity) * nq);
  Vector<uint32_t> count(nq);
  const float r2 = radius * radius;
  parallel_for("probe_pair_masks", nq, BuildPairMask{g, raw(fine), raw(pts), raw(qpts), r2, queries == nullptr,
                                 PairMask{raw(words), raw(count), nq, capacity}, queries ? raw(near) : nullptr,
                                 tensor_tiles});
  std::vector<PairWord> host_words = download(words, words.size());
  std::vector<uint32_t> host_count = download(count, nq);
  const PairMask m{host_words.data(), host_count.data(), nq, capacity};
  out.neighbours.resize(nq);
  for (uint32_t i = 0; i < nq; ++i) {
    auto visit = [&](uint32_t j, Float4, Vec3f, float) { out.neighbours[i].push_back(j); };
    const Vec3f x = xyz(query_pts[i]);
    const uint32_t skip = queries ? kNoSkip : i;
    if (masks_complete(m, m, i)) {
      for_each_pair<false>(g, out.grid.fine_offsets.data(), sorted.data(), x, r2, skip, m, i, visit);
    } else {
      ++out.overflowed;
      for_each_pair<true>(g, out.grid.fine_offsets.data(), sorted.data(), x, r2, skip, m, i, visit);
    }
  }
  return out;
}

struct ClassAt {
  const uint8_t* classes;
  SPHRAY_HD uint8_t operator()(uint32_t i) const { return classes[i]; }
};

inline PartitionBuild partition_three_impl(const std::vector<uint8_t>& classes) {
  const uint32_t n = uint32_t(classes.size());
  Vector<uint8_t> cls;
  upload(cls, classes);
  Vector<uint32_t> first(n), second(n), rest(n), counts(3);
  partition_three("probe_partition", n, ClassAt{raw(cls)}, raw(first), raw(second), raw(rest), raw(counts),
                  raw(counts) + 2);
  const std::vector<uint32_t> c = download(counts, 3);
  return {download(first, c[0]), download(second, c[1]), download(rest, c[2])};
}
