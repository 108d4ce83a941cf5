// The linear BVH build (bvh.h), written once for both backends; included by
// bvh.cpp and bvh_cuda.cu inside their backend namespace.

// 10 bits per axis of a point in the unit cube, interleaved (z high).
SPHRAY_HD SPHRAY_FORCEINLINE uint32_t spread_bits(uint32_t v) {
  v = (v * 0x00010001u) & 0xFF0000FFu;
  v = (v * 0x00000101u) & 0x0F00F00Fu;
  v = (v * 0x00000011u) & 0xC30C30C3u;
  v = (v * 0x00000005u) & 0x49249249u;
  return v;
}

SPHRAY_HD SPHRAY_FORCEINLINE int leading_zeros(uint32_t v) {
#if defined(__CUDA_ARCH__)
  return __clz(int(v));
#else
  return v == 0 ? 32 : __builtin_clz(v);
#endif
}

struct MortonOf {
  const Vec3f* vertices;
  const uint32_t* indices;
  Vec3f lo, scale;  // scale: 1023 / extent
  uint32_t* keys;
  uint32_t* order;
  SPHRAY_HD void operator()(uint32_t t) const {
    const Vec3f c = (vertices[indices[3 * t]] + vertices[indices[3 * t + 1]] + vertices[indices[3 * t + 2]]) * (1.0f / 3.0f);
    auto q = [](float x) { return uint32_t(fminf(fmaxf(x, 0.0f), 1023.0f)); };
    keys[t] = (spread_bits(q((c.z - lo.z) * scale.z)) << 2) | (spread_bits(q((c.y - lo.y) * scale.y)) << 1) |
              spread_bits(q((c.x - lo.x) * scale.x));
    order[t] = t;
  }
};

// The triangles in sorted order, as v0 and edges, each corner with its
// shading normal (BvhTriangle): the area-weighted normals of the corner
// vertex's triangles that lie within the crease angle of this one's.
struct TrianglesOf {
  const Vec3f* vertices;
  const uint32_t* indices;
  const uint32_t* order;
  const uint32_t* vertex_offsets;  // per vertex: its triangles' range in vertex_tris
  const uint32_t* vertex_tris;
  BvhTriangle* tris;
  SPHRAY_HD Vec3f area_normal(uint32_t t) const {  // twice the area times the unit normal
    const Vec3f a = vertices[indices[3 * t]];
    return cross(vertices[indices[3 * t + 1]] - a, vertices[indices[3 * t + 2]] - a);
  }
  SPHRAY_HD void operator()(uint32_t i) const {
    const uint32_t t = order[i];
    const uint32_t ia = indices[3 * t], ib = indices[3 * t + 1], ic = indices[3 * t + 2];
    const Vec3f a = vertices[ia], b = vertices[ib], c = vertices[ic];
    const Vec3f fn = area_normal(t);
    const float fl = std::sqrt(dot(fn, fn));
    const Vec3f face = fl > 0.0f ? fn * (1.0f / fl) : Vec3f{0.0f, 0.0f, 1.0f};
    auto corner = [&](uint32_t v) {
      Vec3f sum{0.0f, 0.0f, 0.0f};
      for (uint32_t k = vertex_offsets[v]; k < vertex_offsets[v + 1]; ++k) {
        const Vec3f n = area_normal(vertex_tris[k]);
        const float l = std::sqrt(dot(n, n));
        if (l > 0.0f && dot(n, face) >= kCreaseCos * l) sum += n;
      }
      const float l = std::sqrt(dot(sum, sum));
      return pack_normal(l > 0.0f ? sum * (1.0f / l) : face);
    };
    tris[i] = {{a.x, a.y, a.z, corner(ia)}, {b.x - a.x, b.y - a.y, b.z - a.z, corner(ib)},
               {c.x - a.x, c.y - a.y, c.z - a.z, corner(ic)}};
  }
};

// Karras (2012), fig. 4: internal node i finds the range of sorted keys it
// covers and where that range splits. Equal keys are told apart by index.
struct InternalNodes {
  const uint32_t* keys;
  uint32_t n;
  BvhNode* nodes;
  uint32_t* parent;  // [internal n - 1][leaves n]
  SPHRAY_HD int delta(int i, int j) const {
    if (j < 0 || j >= int(n)) return -1;
    const uint32_t a = keys[i], b = keys[j];
    return a == b ? 32 + leading_zeros(uint32_t(i) ^ uint32_t(j)) : leading_zeros(a ^ b);
  }
  SPHRAY_HD void operator()(uint32_t ui) const {
    const int i = int(ui);
    const int d = delta(i, i + 1) - delta(i, i - 1) >= 0 ? 1 : -1;
    const int dmin = delta(i, i - d);
    int lmax = 2;
    while (delta(i, i + lmax * d) > dmin) lmax *= 2;
    int l = 0;
    for (int t = lmax / 2; t >= 1; t /= 2)
      if (delta(i, i + (l + t) * d) > dmin) l += t;
    const int j = i + l * d;
    const int dnode = delta(i, j);
    int s = 0, t = l;
    do {
      t = (t + 1) >> 1;
      if (delta(i, i + (s + t) * d) > dnode) s += t;
    } while (t > 1);
    const int gamma = i + s * d + (d < 0 ? -1 : 0);
    const int lo = i < j ? i : j, hi = i < j ? j : i;
    BvhNode& node = nodes[i];
    node.child[0] = lo == gamma ? (uint32_t(gamma) | kLeafBit) : uint32_t(gamma);
    node.child[1] = hi == gamma + 1 ? (uint32_t(gamma + 1) | kLeafBit) : uint32_t(gamma + 1);
    parent[lo == gamma ? n - 1 + gamma : gamma] = uint32_t(i);
    parent[hi == gamma + 1 ? n - 1 + gamma + 1 : gamma + 1] = uint32_t(i);
  }
};

SPHRAY_HD SPHRAY_FORCEINLINE Vec3f vmin(Vec3f a, Vec3f b) { return {fminf(a.x, b.x), fminf(a.y, b.y), fminf(a.z, b.z)}; }
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f vmax(Vec3f a, Vec3f b) { return {fmaxf(a.x, b.x), fmaxf(a.y, b.y), fmaxf(a.z, b.z)}; }

// Boxes bottom-up: each leaf walks toward the root; at each node the first
// child to arrive stops, the second (whose sibling is then complete) writes
// the node's two child boxes and goes on.
struct BoundsUp {
  const BvhTriangle* tris;
  const uint32_t* parent;
  uint32_t n;
  BvhNode* nodes;
  uint32_t* arrivals;  // per internal node, zeroed before
  SPHRAY_HD void child_box(uint32_t ref, Vec3f& lo, Vec3f& hi) const {
    if (ref & kLeafBit) {
      const BvhTriangle t = tris[ref & ~kLeafBit];
      const Vec3f a = xyz(t.v0), b = a + xyz(t.e1), c = a + xyz(t.e2);
      lo = vmin(a, vmin(b, c));
      hi = vmax(a, vmax(b, c));
      return;
    }
    // Written by another thread before its arrival: read past the L1 cache.
    const volatile BvhNode* v = nodes + ref;
    lo = {fminf(v->lo[0].x, v->lo[1].x), fminf(v->lo[0].y, v->lo[1].y), fminf(v->lo[0].z, v->lo[1].z)};
    hi = {fmaxf(v->hi[0].x, v->hi[1].x), fmaxf(v->hi[0].y, v->hi[1].y), fmaxf(v->hi[0].z, v->hi[1].z)};
  }
  SPHRAY_HD void operator()(uint32_t leaf) const {
    uint32_t node = parent[n - 1 + leaf];
    while (true) {
      if (atomic_arrive(arrivals + node) == 0) return;
      BvhNode& nd = nodes[node];
      for (int c = 0; c < 2; ++c) {
        Vec3f lo, hi;
        child_box(nd.child[c], lo, hi);
        volatile float* out_lo = &nd.lo[c].x;
        volatile float* out_hi = &nd.hi[c].x;
        out_lo[0] = lo.x; out_lo[1] = lo.y; out_lo[2] = lo.z;
        out_hi[0] = hi.x; out_hi[1] = hi.y; out_hi[2] = hi.z;
      }
      if (node == 0) return;
      node = parent[node];
    }
  }
};

class BvhImpl final : public Bvh {
 public:
  BvhImpl(const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices)
      : n_(uint32_t(indices.size() / 3)) {
    if (n_ == 0) return;
    upload(indices_, indices);
    take_vertices(vertices);
    take_adjacency(vertices.size(), indices);
    const Vec3f lo = lo_, e = hi_ - lo_;
    auto s = [](float x) { return x > 0 ? 1023.0f / x : 0.0f; };
    keys_.resize(n_);
    order_.resize(n_);
    tris_.resize(n_);
    nodes_.resize(n_ > 1 ? n_ - 1 : 1);
    parent_.resize(2 * size_t(n_));
    arrivals_.resize(n_);
    clock_.start();
    parallel_for("bvh_morton", n_, MortonOf{raw(vertices_), raw(indices_), lo, {s(e.x), s(e.y), s(e.z)}, raw(keys_), raw(order_)});
    sort_pairs(keys_, order_, n_, 30);
    triangles();
    if (n_ > 1) parallel_for("bvh_nodes", n_ - 1, InternalNodes{raw(keys_), n_, raw(nodes_), raw(parent_)});
    boxes();
    clock_.end_of("build");
    clock_.finish();
    ms_ = clock_.ms("build");
  }

  Backend backend() const override { return kBackend; }
  MeshView view() const override {
    MeshView v;
    v.nodes = raw(nodes_);
    v.tris = raw(tris_);
    v.num_tris = n_;
    v.root = n_ > 1 ? 0u : kLeafBit;
    v.lo = lo_;
    v.hi = hi_;
    return v;
  }
  double last_ms() const override { return ms_; }
  std::vector<uint32_t> input_order() const override { return download(order_, n_); }

  void refit(const std::vector<Vec3f>& vertices) override {
    if (n_ == 0) return;
    take_vertices(vertices);
    clock_.start();
    triangles();
    boxes();
    clock_.end_of("refit");
    clock_.finish();
    ms_ = clock_.ms("refit");
  }

 private:
  // The vertices onto the device, and the whole mesh's box.
  void take_vertices(const std::vector<Vec3f>& vertices) {
    lo_ = hi_ = vertices.at(0);
    for (const Vec3f& v : vertices) {
      lo_ = vmin(lo_, v);
      hi_ = vmax(hi_, v);
    }
    upload(vertices_, vertices);
  }

  // The sorted triangles from the current vertices, with their corners' normals.
  void triangles() {
    parallel_for("bvh_triangles", n_, TrianglesOf{raw(vertices_), raw(indices_), raw(order_), raw(vertex_offsets_),
                                                  raw(vertex_tris_), raw(tris_)});
  }

  // Each vertex's triangles (for the corners' normals), once: counted, then listed.
  void take_adjacency(size_t num_vertices, const std::vector<uint32_t>& indices) {
    std::vector<uint32_t> offsets(num_vertices + 1, 0), tris(indices.size());
    for (const uint32_t v : indices) ++offsets[v + 1];
    for (size_t v = 0; v < num_vertices; ++v) offsets[v + 1] += offsets[v];
    std::vector<uint32_t> fill(offsets.begin(), offsets.end() - 1);
    for (size_t k = 0; k < indices.size(); ++k) tris[fill[indices[k]]++] = uint32_t(k / 3);
    upload(vertex_offsets_, offsets);
    upload(vertex_tris_, tris);
  }

  void boxes() {
    if (n_ < 2) return;
    thrust::fill(policy(), arrivals_.begin(), arrivals_.end(), 0u);
    parallel_for("bvh_boxes", n_, BoundsUp{raw(tris_), raw(parent_), n_, raw(nodes_), raw(arrivals_)});
  }

  uint32_t n_;
  Vec3f lo_{}, hi_{};
  double ms_ = 0;
  StageClock clock_;
  Vector<Vec3f> vertices_;
  Vector<uint32_t> vertex_offsets_, vertex_tris_;  // each vertex's triangles (take_adjacency)
  Vector<uint32_t> indices_, keys_, order_, parent_, arrivals_;
  Vector<BvhTriangle> tris_;
  Vector<BvhNode> nodes_;
};
