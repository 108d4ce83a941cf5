// The field builders' driver, written once for both backends. Included by
// field_cpu.cpp and field_cuda.cu inside their backend namespace (which
// supplies Vector, raw, policy, parallel_for, download, StageClock, kBackend),
// after nsearch/sort.inl.

struct CounterToU64 {
  const uint32_t* c;
  SPHRAY_HD uint64_t operator()(uint32_t i) const { return c[i]; }
};

struct IsPositive {
  SPHRAY_HD bool operator()(uint32_t c) const { return c > 0; }
};

// Launches over n items the functor that make(count_tag, group_tag,
// aniso_tag) returns, for its sixteen instantiations (counted or not; 1, 4,
// 8 or 32 threads per particle; spheres or ellipsoids).
template <class Make>
void launch_variant(const char* name, uint32_t n, bool count, int group, bool aniso, Make&& make) {
  auto with_aniso = [&](auto c, auto g) {
    if (aniso) parallel_for(name, n, make(c, g, std::true_type{}));
    else parallel_for(name, n, make(c, g, std::false_type{}));
  };
  auto with_group = [&](auto c) {
    switch (group) {
      case 4: with_aniso(c, std::integral_constant<int, 4>{}); break;
      case 8: with_aniso(c, std::integral_constant<int, 8>{}); break;
      case 32: with_aniso(c, std::integral_constant<int, 32>{}); break;
      default: with_aniso(c, std::integral_constant<int, 1>{}); break;
    }
  };
  if (count) with_group(std::true_type{});
  else with_group(std::false_type{});
}

class FieldBuilderImpl final : public FieldBuilder {
 public:
  FieldBuilderImpl(const FieldSetup& s, FieldKind kind) : setup_(s), kind_(kind) { field_.resize(size_t(s.geom.num_voxels())); }

  Backend backend() const override { return kBackend; }
  const FieldSetup& setup() const override { return setup_; }
  FieldKind kind() const override { return kind_; }
  double last_ms() const override { return ms_; }
  double last_anisotropy_ms() const override { return aniso_ms_; }
  const FieldCounts& last_counts() const override { return counts_; }
  const float* data() const override { return raw(field_); }
  size_t device_bytes() const override {
    return field_.size() * sizeof(float) + counters_.size() * sizeof(uint32_t) + full_cells_.size() +
           ellipsoids_.size() * sizeof(Float4) +
           (aniso_keys_.size() + aniso_order_.size() + aniso_offsets_.size()) * sizeof(uint32_t) +
           aniso_pos_.size() * sizeof(Float4);
  }
  std::vector<float> download() const override { return sphray::SPHRAY_BK::download(field_, field_.size()); }

  void build(const ParticleView& pv, bool count, int group) override {
    const FieldKind kind = kind_;
    if (pv.backend != kBackend)
      throw std::invalid_argument(std::string("field builder on the ") + backend_name(kBackend) +
                                  " backend was given particles of the " + backend_name(pv.backend) + " backend");
    const bool zb = setup_.kernel == FieldKernel::ZhuBridson, aniso = setup_.kernel == FieldKernel::Anisotropic;
    if (group == 0) group = zb ? zhu_bridson_group(setup_) : default_group(kind, pv.n);
    if (zb && group > 1 && kBackend != Backend::Cuda)
      throw std::invalid_argument("field builder: the CPU builds Zhu & Bridson's surface with one thread per voxel (got " +
                                  std::to_string(group) + ")");
    if (!valid_group(group))
      throw std::invalid_argument("field builder: threads per particle must be 1, 4, 8 or 32 (got " + std::to_string(group) + ")");
    const VolumeGeom& vol = setup_.geom;
    const FieldShape& shape = setup_.shape;
    const uint32_t voxels = uint32_t(vol.num_voxels());
    const uint64_t items64 = kind == FieldKind::Gather ? uint64_t(voxels) * uint64_t(zb ? group : 1)
                                                       : uint64_t(pv.n) * uint64_t(group);
    if (items64 > 0xffffffffull - 31u)
      throw std::invalid_argument(std::string("field builder: too many ") +
                                  (kind == FieldKind::Gather ? "voxels" : "particles") + " for " +
                                  std::to_string(group) + " threads each");
    const uint32_t items = uint32_t(items64);
    CounterSink sink{nullptr, items};
    if (count) {
      if (counters_.size() < size_t(kNumCounters) * items) counters_.resize(size_t(kNumCounters) * items);
      sink.counts = raw(counters_);
    }
    float* f = raw(field_);
    if (zb && kind != FieldKind::Gather)
      throw std::invalid_argument("field builder: Zhu & Bridson's surface is built by the gather builder only");
    if (aniso && kind == FieldKind::Gather)
      throw std::invalid_argument("field builder: the gather builder splats spheres only (anisotropic kernels: naive or presence)");
    if (aniso && !pv.fine_offsets) throw std::invalid_argument("field builder: anisotropic kernels need the grid's slab table");
    const Float4* ell = nullptr;
    if (aniso && ellipsoids_.size() < 3 * size_t(pv.n)) ellipsoids_.resize(3 * size_t(pv.n));
    clock_.start();
    // Presence: the full cells and the coarse fill first, so that the
    // ellipsoids' pass can mark the occupied voxels (pass 2) as it computes
    // each ellipsoid.
    const uint8_t* full_cells = nullptr;
    if (kind == FieldKind::Presence) {
      if (setup_.mark_occupied) {
        if (full_cells_.size() < pv.grid.num_cells()) full_cells_.resize(pv.grid.num_cells());
        const FullCellFlags flags{vol, pv.grid, pv.offsets, setup_.full_count, setup_.face_count, raw(full_cells_)};
        parallel_for("field_full_cells", flags.num_items(), flags);
        full_cells = raw(full_cells_);
      }
      const CoarseFill fill{vol, pv.grid, pv.offsets, shape.coarse, setup_.full_fill, full_cells, f};
      parallel_for("field_fill", fill.num_items(), fill);
    }
    // The full cells are saturated where the fill wrote the clip value into them.
    const FullCells full{vol, pv.grid, setup_.full_fill >= shape.clip ? full_cells : nullptr};
    clock_.end_of("fill");
    if (aniso) {
      float* mark = kind == FieldKind::Presence && setup_.mark_occupied ? f : nullptr;
      // The solver's neighbour loop may have summed the covariance already
      // (ParticleView::covariance): only the ellipsoids are left to compute.
      if (pv.covariance && pv.covariance_radius == setup_.aniso.radius &&
          pv.covariance_mirror_walls == setup_.aniso.walls.mirror) {
        parallel_for("field_anisotropy_from_sums", pv.n,
                     EllipsoidPass<AnisotropyFromSums>{
                         {pv.pos, pv.covariance, pv.n, vol, setup_.aniso, raw(ellipsoids_)}, mark, shape});
      } else {
        // Where the pass sums each neighbourhood itself, the presence builder
        // leaves out the particles deep in full cells first (from the solver's
        // sums the ellipsoid costs less than that test: docs/field.md).
        const bool leave_out = kind == FieldKind::Presence && setup_.leave_out_buried;
        const FullCells cells{vol, pv.grid, leave_out ? full.flags : nullptr};
        const GridGeom ag = sort_by_radius(pv, field_sort_radius(setup_));
        parallel_for("field_anisotropy", pv.n,
                     EllipsoidPass<ComputeAnisotropy>{
                         {ag, raw(aniso_offsets_), raw(aniso_pos_), raw(aniso_order_), pv.n, vol, setup_.aniso,
                          raw(ellipsoids_)},
                         mark, shape, cells, pv.presence, EllipsoidBound::of(setup_.aniso, vol)});
      }
      ell = raw(ellipsoids_);
    }
    clock_.end_of("anisotropy");
    switch (kind) {
      case FieldKind::Naive:
        thrust::fill(policy(), field_.begin(), field_.end(), 0.0f);
        launch_variant("naive_splat", items, count, group, aniso, [&](auto c, auto g, auto a) {
          return NaiveSplat<decltype(c)::value, decltype(g)::value, decltype(a)::value>{vol, shape, pv.pos, ell, pv.n, f, sink};
        });
        break;
      case FieldKind::Presence:
        if (setup_.mark_occupied && !aniso)
          parallel_for("field_mark_occupied", pv.n, MarkOccupied{vol, shape, pv.pos, pv.n, f});
        launch_variant("presence_splat", items, count, group, aniso, [&](auto c, auto g, auto a) {
          return PresenceSplat<decltype(c)::value, decltype(g)::value, decltype(a)::value>{
              vol, shape, pv.pos, ell, pv.presence, pv.n, f, sink, full};
        });
        break;
      case FieldKind::Gather:
        if (zb) {
          const GridGeom zg = sort_by_radius(pv, field_sort_radius(setup_));
          const uint32_t launched = group > 1 ? (items + 31u) / 32u * 32u : items;  // whole warps (ZhuBridsonGather)
          launch_variant("zhu_bridson_field", launched, count, group, false, [&](auto c, auto g, auto) {
            return ZhuBridsonGather<decltype(c)::value, decltype(g)::value>{
                vol, pv.grid, pv.offsets, zg, raw(aniso_offsets_), raw(aniso_pos_), shape, setup_.zhu_bridson, f, sink,
                items};
          });
        } else
          launch_variant("gather_field", items, count, 1, false, [&](auto c, auto, auto) {
            return GatherField<decltype(c)::value>{vol, pv.grid, shape, pv.offsets, pv.pos, f, sink};
          });
        break;
    }
    clock_.end_of("field");
    clock_.finish();
    aniso_ms_ = clock_.ms("anisotropy");
    ms_ = clock_.ms("fill") + aniso_ms_ + clock_.ms("field");
    counts_ = FieldCounts{};
    counts_.init_writes = kind == FieldKind::Gather ? 0 : voxels;
    if (count) {
      uint64_t total[kNumCounters];
      for (uint32_t c = 0; c < kNumCounters; ++c)
        total[c] = thrust::transform_reduce(policy(), thrust::counting_iterator<uint32_t>(0),
                                            thrust::counting_iterator<uint32_t>(items),
                                            CounterToU64{raw(counters_) + size_t(c) * items}, uint64_t(0),
                                            thrust::plus<uint64_t>());
      counts_.pairs = total[kPairs];
      counts_.touched = total[kTouched];
      counts_.atomics = total[kAtomics];
      counts_.skipped = total[kSkipped];
      const uint32_t* pairs = raw(counters_) + size_t(kPairs) * items;
      counts_.working = uint64_t(thrust::count_if(policy(), pairs, pairs + items, IsPositive{}));
      counts_.longest = thrust::reduce(policy(), pairs, pairs + items, 0u, thrust::maximum<uint32_t>());
      counts_.counted = true;
    }
  }

 private:
  // Threads per particle when the caller leaves it open (docs/field.md,
  // "Threads per particle", has the measurements): one on the CPU. On the
  // GPU the naive splat, whose adds are fire-and-forget, runs 8 per particle
  // (fewest stalls on its box loop at 125k-4M). The presence splat, which
  // reads its voxels before it adds (in batches, PresenceSplat), runs 4 per
  // particle while that fills the GPU at most twice over (H100: up to 135k
  // particles), else 1.
  // Zhu & Bridson's gather: threads per voxel. A voxel's reach of R voxels
  // holds 8x the particles at each coarser refine (about 130 at refine 2,
  // 1,000 at 1, 8,000 at 0) for 8x fewer voxels: one thread per voxel at
  // refine 2, where the voxels fill the GPU; at coarser voxels one thread
  // each left it nearly idle on long loops (docs/field.md, "Zhu & Bridson's
  // surface"): 8 at refine 1, and at refine 0 a warp while that fills the
  // GPU at most twice over, else 8 (8 lanes shuffle less, and enough
  // voxels fill the GPU with them). One on the CPU.
  static int zhu_bridson_group(const FieldSetup& s) {
    if (kBackend != Backend::Cuda) return 1;
    if (s.geom.refine >= 2) return 1;
    if (s.geom.refine == 1) return 8;
    return s.geom.num_voxels() * 32u <= 2ull * resident_threads() ? 32 : 8;
  }

  static int default_group(FieldKind kind, uint32_t n) {
    if (kBackend != Backend::Cuda || kind == FieldKind::Gather) return 1;
    if (kind == FieldKind::Naive) return 8;
    return uint64_t(n) * 4u <= 2ull * resident_threads() ? 4 : 1;
  }

  // The view's particles sorted by a grid of cells of half `radius` [m] over
  // the view grid's extent (anisotropy.h, anisotropy_grid), for the passes
  // that read every particle within `radius` of a point (the ellipsoids'
  // covariance, Zhu & Bridson's surface): their positions in that order, the
  // order, and the grid's slab table.
  GridGeom sort_by_radius(const ParticleView& pv, float radius) {
    const GridGeom g = anisotropy_grid(pv.grid, radius);
    if (!g.fine_cells_indexable())
      throw std::invalid_argument("field builder: the grid of half the field's reach has more than 2^32 slabs (raise "
                                  "sph.spacing, field.anisotropy.radius or field.zhu_bridson.radius)");
    const uint32_t n = pv.n;
    aniso_keys_.resize(n);
    aniso_order_.resize(n);
    aniso_pos_.resize(n);
    aniso_offsets_.resize(size_t(g.num_fine_cells()) + 1);
    parallel_for("field_anisotropy_keys", n, KeyOf<Float4>{g, pv.pos, raw(aniso_keys_)});
    sort_and_offsets(g, n, aniso_keys_, aniso_order_, aniso_offsets_, nullptr);
    thrust::gather(policy(), aniso_order_.begin(), aniso_order_.begin() + n, pv.pos, aniso_pos_.begin());
    return g;
  }

  FieldSetup setup_;
  FieldKind kind_;
  Vector<float> field_;
  Vector<uint32_t> counters_;
  Vector<uint8_t> full_cells_;  // FullCellFlags (presence, mark_occupied)
  Vector<Float4> ellipsoids_;  // [3][n] (anisotropic kernels)
  Vector<uint32_t> aniso_keys_, aniso_order_, aniso_offsets_;  // sort_by_radius
  Vector<Float4> aniso_pos_;
  StageClock clock_;
  double ms_ = 0, aniso_ms_ = 0;
  FieldCounts counts_;
};
