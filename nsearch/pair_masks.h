// The neighbour loops every stage shares: particles of one grid-sorted set
// within the support radius of a position, found either directly from the
// grid's candidate rows, or through a pair mask built once per grid.
//
// Why pair masks: on the GPU a warp runs 32 queries in lock step. In the direct
// loop each lane tests its own next candidate, and about 3 in 10 candidates
// are neighbours, so in nearly every iteration some lane has a neighbour and
// the whole warp executes the pair physics: a candidate then costs the test
// plus the physics, whatever the culling saved. With a mask the candidate
// tests run once per step in a pass of their own (no physics), and the
// pair loop (interaction.h) visits only the set bits, one neighbour per lane per
// iteration, so the pair physics runs with (nearly) all lanes busy.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/vec.h"
#include "grid.h"
#include "tile_mma.h"

namespace sphray {

// Calls f(j, p_j, r, r2) for every particle j of `pts` (sorted by `g`, slab
// table `offsets`) with |r|^2 = r2 < support2, where r = x - x_j, except j == skip
// (pass the particle's own index, or UINT32_MAX for another set).
template <class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_neighbour(const GridGeom& g, const uint32_t* offsets, const Float4* pts,
                                                     Vec3f x, float support2, uint32_t skip, F&& f) {
  for_each_candidate(g, offsets, x, [&](uint32_t j) {
    const Float4 pj = load(pts + j);
    const Vec3f r = x - xyz(pj);
    const float r2 = length2(r);
    if (r2 >= support2 || j == skip) return;
    f(j, pj, r, r2);
  });
}

constexpr uint32_t kNoSkip = 0xffffffffu;

// Index of the lowest set bit of a non-zero word.
SPHRAY_HD SPHRAY_FORCEINLINE uint32_t lowest_bit(uint32_t w) {
#if defined(__CUDA_ARCH__)
  return uint32_t(__ffs(int(w)) - 1);
#else
  return uint32_t(__builtin_ctz(w));
#endif
}

// One word of a query's pair mask: bit k says whether candidate base + k (of a
// row ending at `end`) is a neighbour: r2 < support2 and not `skip`.
SPHRAY_HD SPHRAY_FORCEINLINE uint32_t pair_word(const Float4* pts, Vec3f x, float support2, uint32_t skip, uint32_t base,
                                                uint32_t end) {
  const uint32_t count = end - base < 32u ? end - base : 32u;
  uint32_t word = 0;
  for (uint32_t k = 0; k < count; ++k) {
    const uint32_t j = base + k;
    const float r2 = length2(x - xyz(load(pts + j)));
    word |= uint32_t(r2 < support2 && j != skip) << k;
  }
  return word;
}

// Pair masks of n queries against one particle set: for query i, the
// non-zero words of its candidate rows (grid.h) in order, a row's candidates
// taken 32 at a time, each word stored with the index of its first candidate
// (bit k: candidate base + k is a neighbour). Word w of query i is
// words[w * n + i] (the queries of a warp read neighbouring words). A query
// needing more than `capacity` words (a compressed or piled-up state) stores
// count = capacity + 1 and its loops take the direct path: the mask is never
// wrong there, only no faster. The loops run in two launches, one for the
// queries whose masks hold all their words and one, the direct loop, for the
// others (for_each_pair), so that the common kernel carries no fallback code
// (it took 13 more registers and spilled under the 40-register cap).
struct alignas(8) PairWord {
  uint32_t base;  // sorted index of the word's first candidate
  uint32_t bits;
};

struct PairMask {
  PairWord* words;
  uint32_t* count;    // words of each query, or capacity + 1
  uint32_t n;
  uint32_t capacity;  // words kept per query
};

// Words per query to keep for a support of `support_over_dx` particle
// spacings: a query reads about 15 cell volumes of candidates (grid.h; 14.5
// measured at 2 dx), i.e. 15 (support / dx)^3 at rest density, at most one word
// per 32 plus one partial word per row, with a quarter to spare for
// compression. Clamped to [8, 256].
inline uint32_t pair_mask_capacity(double support_over_dx) {
  const double candidates = 15.0 * support_over_dx * support_over_dx * support_over_dx;
  const double words = 1.25 * (candidates / 32.0 + kCandidateRows);
  return uint32_t(std::min(256.0, std::max(8.0, std::ceil(words))));
}

// Builds the pair mask of query i (position queries[i]) against `pts`.
//
// On the GPU the 32 queries of a warp build their masks together: consecutive
// sorted particles share most of their candidate rows, so per row the warp
// loads the union of its lanes' ranges 32 candidates at a time into shared
// memory (one coalesced load) and every lane tests each of them from there
// (a broadcast read), keeping those within its own range; a full warp whose
// queries lie close together tests the whole 32 x 32 tile on the tensor
// cores instead (tile_mma.h). Loading each lane's
// own candidates instead (the CPU path below) makes 32 scattered reads per
// candidate, and such a kernel is bound by the L1 cache (docs/notebook/benchmarks-history.md).
// A row whose lanes lie in different rows of the
// grid (the union far longer than any lane's range) is built per lane. Either
// way a lane's words hold its own neighbours in the order of for_each_neighbour;
// where the words start differs, and the tile's test may add a candidate within
// a relative 1e-4 of the support squared (kTileSlack), which weighs zero.
struct BuildPairMask {
  // Relative slack of the GPU's shared-tile test (below): a superset of the
  // exact neighbours, never a subset.
  static constexpr float kTileSlack = 1e-4f;
  // Registers per thread on the GPU (core/launch_cuda.cuh): the tensor-core
  // test keeps the warp's A fragments in registers; at 56 the kernel spills,
  // and under the file-wide 40 it spilled more. 72 rather than 64: faster
  // despite the lower occupancy (docs/notebook/benchmarks-history.md), and
  // the tile loaded ahead (below) spills at 64.
  static constexpr int kMaxRegisters = 72;
  GridGeom grid;
  const uint32_t* offsets;  // slab table of pts
  const Float4* pts;
  const Float4* queries;
  float support2;
  bool self;  // queries and pts are the same set: skip j == i
  PairMask mask;
  // CellsNear of pts (grid.h), or null: a query in an unflagged cell has no
  // candidates (the wall masks of the fluid far from every wall).
  const uint8_t* near = nullptr;
  // The tile test on the tensor cores where the GPU has them (tile_mma.h);
  // false: the FMA test everywhere.
  bool tensor_tiles = true;
  // The candidate search radius (grid.h, candidate_row): 0 for the cell
  // size; the support where the support is smaller than the cells.
  float search_radius = 0.0f;

  // Appends one word (if it has a neighbour) to query i's mask; w counts the
  // query's words, capacity + 1 at most (the overflow mark).
  SPHRAY_HD SPHRAY_FORCEINLINE void put(uint32_t i, uint32_t& w, uint32_t base, uint32_t bits) const {
    if (bits == 0 || w > mask.capacity) return;
    if (w < mask.capacity) mask.words[size_t(w) * mask.n + i] = {base, bits};
    ++w;
  }

  // The bits of the word starting at `base` that are the query's own
  // candidates: within [begin, end), and not `skip`.
  SPHRAY_HD SPHRAY_FORCEINLINE static uint32_t own_bits(uint32_t base, uint32_t begin, uint32_t end, uint32_t skip) {
    const uint32_t kb = begin > base ? begin - base : 0u, ke = end > base ? end - base : 0u;
#if defined(__CUDA_ARCH__)
    // ~0 << min(k, 32) and 1 << min(k, 32) (0 for k >= 32) as clamped funnel
    // shifts, one instruction each; it runs once per tile and lane.
    return ~__funnelshift_lc(0u, ~0u, ke) & __funnelshift_lc(0u, ~0u, kb) & ~__funnelshift_lc(0u, 1u, skip - base);
#else
    const uint32_t below_end = ke >= 32u ? 0xffffffffu : (1u << ke) - 1u;
    const uint32_t from_begin = kb >= 32u ? 0u : ~((1u << kb) - 1u);
    const uint32_t not_skip = skip - base < 32u ? ~(1u << (skip - base)) : 0xffffffffu;
    return below_end & from_begin & not_skip;
#endif
  }

  // Appends the words of one of the query's own rows, [begin, end), each
  // word's candidates loaded by this query alone (stops once overflowed).
  SPHRAY_HD SPHRAY_FORCEINLINE void put_row(uint32_t i, uint32_t& w, Vec3f x, uint32_t skip, uint32_t begin,
                                            uint32_t end) const {
    for (uint32_t base = begin; base < end && w <= mask.capacity; base += 32u)
      put(i, w, base, pair_word(pts, x, support2, skip, base, end));
  }

#if defined(__CUDA_ARCH__)
  // The FMA tile test: the bits of the tile pts[base, base + count) for the
  // query at x, the warp's `lanes` loading the tile into t together. The tile
  // is taken relative to its first candidate, o: with y = x - o,
  // |y - t|^2 < s^2  <=>  |t|^2 - 2 y.t < s^2 - |y|^2, three FMAs and a
  // compare per candidate instead of the difference, its square and the
  // compare. Relative to o the magnitudes stay within a few supports for
  // every lane the word can hold bits for (own_bits), so the rounding is a
  // few 1e-7 of s^2; the test takes s^2 (1 + kTileSlack), so that it never
  // drops a neighbour. It may keep a candidate a hair beyond the support,
  // which the loops weigh zero (for_each_masked_neighbour). Padding: never
  // within reach.
  __device__ __forceinline__ uint32_t fma_tile(Vec3f x, uint32_t base, uint32_t count, uint32_t active,
                                               uint32_t lanes, Float4* t) const {
    const uint32_t lane = threadIdx.x % 32;
    const Vec3f o = xyz(load(pts + base));
    for (uint32_t k = lane; k < 32u; k += active) {
      if (k < count) {
        const Vec3f r = xyz(load(pts + base + k)) - o;
        t[k] = {r.x, r.y, r.z, length2(r)};
      } else {
        t[k] = {0.0f, 0.0f, 0.0f, 1e30f};
      }
    }
    const Vec3f y = x - o;
    const float mx = -2.0f * y.x, my = -2.0f * y.y, mz = -2.0f * y.z;
    const float reach = support2 * (1.0f + kTileSlack) - length2(y);
    __syncwarp(lanes);
    uint32_t bits = 0;
#pragma unroll
    for (uint32_t k = 0; k < 32u; ++k) {
      const Float4 c = t[k];
      bits |= uint32_t(fmaf(mz, c.z, fmaf(my, c.y, fmaf(mx, c.x, c.w))) < reach) << k;
    }
    __syncwarp(lanes);
    return bits;
  }
#endif

  SPHRAY_HD void operator()(uint32_t i) const {
    const Vec3f x = xyz(queries[i]);
    const uint32_t skip = self ? i : kNoSkip;
    // No particle of pts within a cell of x: no words (on the GPU when the
    // whole warp has none; a lane among others finds its rows empty anyway).
    const bool none = near != nullptr && !cell_near(grid, near, x);
    uint32_t w = 0;
#if defined(__CUDA_ARCH__)
    __shared__ Float4 tile[kThreadsPerBlock / 32][32];
    Float4* t = tile[threadIdx.x / 32];
    // The lanes that run this (parallel_for: i = block * kThreadsPerBlock +
    // thread, and only i < n call in): the first `active` of the warp. Derived
    // from i and n rather than __activemask(), which need not return all of
    // them, nor a prefix, where the warp has not reconverged.
    const uint32_t lane = threadIdx.x % 32, warp_first = i - lane;
    const uint32_t active = mask.n - warp_first < 32u ? mask.n - warp_first : 32u;
    const uint32_t lanes = active == 32u ? 0xffffffffu : (1u << active) - 1u;
    if (__all_sync(lanes, none)) {
      mask.count[i] = 0;
      return;
    }
#if defined(SPHRAY_TILE_MMA)
    // The tile test on the tensor cores (tile_mma.h) for a full warp whose
    // queries lie close enough together; the FMA test below otherwise.
    __shared__ __align__(16) uint32_t mma_words[kThreadsPerBlock / 32][TileMma::kSharedWords];
    uint32_t* mma_shared = mma_words[threadIdx.x / 32];
    TileMma mma;
    const bool tensor = tensor_tiles && active == 32u && mma.setup(x, support2, kTileSlack, mma_shared);
#endif
    for (int row = 0; row < kCandidateRows; ++row) {
      uint32_t begin = 0, end = 0;
      if (!candidate_row(grid, offsets, x, row, begin, end, search_radius) || begin >= end) begin = 0xffffffffu, end = 0;
      const uint32_t lo = __reduce_min_sync(lanes, begin), hi = __reduce_max_sync(lanes, end);
      const uint32_t longest = __reduce_max_sync(lanes, end > begin ? end - begin : 0u);
      if (hi <= lo) continue;  // no lane has candidates in this row
      if (hi - lo > 2 * longest + 64) {  // the lanes read different grid rows: each its own
        put_row(i, w, x, skip, begin, end);
        continue;
      }
#if defined(SPHRAY_TILE_MMA)
      // The tensor test's candidates loaded one tile ahead: the test waits
      // on nothing else (the words it stores are not read back here).
      Vec3f ahead = {0.0f, 0.0f, 0.0f};
      if (tensor && lo + lane < hi) ahead = xyz(load(pts + lo + lane));
#endif
      for (uint32_t base = lo; base < hi; base += 32u) {
        const uint32_t count = hi - base < 32u ? hi - base : 32u;
#if defined(SPHRAY_TILE_MMA)
        const Vec3f candidate = ahead;
        if (tensor && base + 32u + lane < hi) ahead = xyz(load(pts + base + 32u + lane));
        const uint32_t bits =
            tensor ? mma.bits(candidate, count, mma_shared) : fma_tile(x, base, count, active, lanes, t);
#else
        const uint32_t bits = fma_tile(x, base, count, active, lanes, t);
#endif
        put(i, w, base, bits & own_bits(base, begin, end, skip));
      }
    }
#else
    if (none) {
      mask.count[i] = 0;
      return;
    }
    for (int row = 0; row < kCandidateRows && w <= mask.capacity; ++row) {
      uint32_t begin = 0, end = 0;
      if (candidate_row(grid, offsets, x, row, begin, end, search_radius)) put_row(i, w, x, skip, begin, end);
    }
#endif
    mask.count[i] = w;
  }
};

// Calls f(j, fetch(j)) for every set bit j of query i's pair mask: the
// neighbours of for_each_neighbour, in its order (rows in order, j ascending).
// One flat loop, one neighbour per iteration: the lanes of a warp step through
// their neighbours together, each loading its next word when its current one
// is spent. fetch(j) loads what f needs of neighbour j (its position and
// whatever else the loop reads of it). f must weigh a pair at or beyond the
// support zero (the kernels do: dW/dr vanishes there), as the GPU build may
// keep one a hair beyond it (BuildPairMask::kTileSlack).
// Visits nothing for a query whose mask overflowed (see for_each_pair).
// The next word is loaded one word ahead: the words are written by the build
// and read once here, so they come from DRAM, and a lane that waited for its
// next word would hold up the whole warp every few neighbours. The switch to
// the next word is written as selects and a predicated load, run by every
// lane on every neighbour: with 32 lanes, one of them switches on nearly
// every iteration, and as a branch the others waited for it each time.
template <class Fetch, class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_masked(const PairMask& m, uint32_t i, Fetch&& fetch, F&& f) {
  const uint32_t count = m.count[i];
  if (count > m.capacity) return;
  uint32_t w = 0, base = 0, bits = 0;
  // The next word's address, stepped by n (word w of query i is words[w n + i]):
  // one add per word instead of the index arithmetic and the reload of
  // `words` and n that the loop's register budget made of it.
  const PairWord* word = m.words + i;
  PairWord ahead = count > 0 ? *word : PairWord{0u, 0u};
  auto next = [&](uint32_t& j) {
    const bool take = bits == 0;  // no stored word is empty (BuildPairMask::put)
    if (take && w == count) return false;
    base = take ? ahead.base : base;
    bits = take ? ahead.bits : bits;
    w += take ? 1u : 0u;
    const bool more = take && w < count;
    word = more ? word + m.n : word;
    ahead = more ? *word : ahead;
    j = base + lowest_bit(bits);
    bits &= bits - 1u;
    return true;
  };
  uint32_t j = 0;
  while (next(j)) f(j, fetch(j));
}

// for_each_masked with the neighbour's position loaded: f(j, p_j, r, r2),
// r = x - x_j; r2 is recomputed here.
template <class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_masked_neighbour(const Float4* pts, Vec3f x, const PairMask& m, uint32_t i,
                                                            F&& f) {
  for_each_masked(m, i, [&](uint32_t j) { return load(pts + j); }, [&](uint32_t j, const Float4& pj) {
    const Vec3f r = x - xyz(pj);
    f(j, pj, r, length2(r));
  });
}

// Whether query i's mask holds all its words (its loops take the mask).
SPHRAY_HD SPHRAY_FORCEINLINE bool mask_complete(const PairMask& m, uint32_t i) { return m.count[i] <= m.capacity; }

// Whether both masks of query i hold all their words.
SPHRAY_HD SPHRAY_FORCEINLINE bool masks_complete(const PairMask& a, const PairMask& b, uint32_t i) {
  return mask_complete(a, i) && mask_complete(b, i);
}

// The neighbour loop of a launch: the mask walk (Direct = false), or the direct
// loop (Direct = true) for the queries whose masks overflowed. A stage runs
// both launches; each query does its work in exactly one (masks_complete).
template <bool Direct, class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_pair(const GridGeom& g, const uint32_t* offsets, const Float4* pts, Vec3f x,
                                                float support2, uint32_t skip, const PairMask& m, uint32_t i, F&& f) {
  if constexpr (Direct) for_each_neighbour(g, offsets, pts, x, support2, skip, f);
  else for_each_masked_neighbour(pts, x, m, i, f);
}

// The same with a fetch: f(j, fetch(j)) for every neighbour j (for_each_masked;
// the direct loop finds j by the positions in pts, then fetches).
template <bool Direct, class Fetch, class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_pair(const GridGeom& g, const uint32_t* offsets, const Float4* pts, Vec3f x,
                                                float support2, uint32_t skip, const PairMask& m, uint32_t i,
                                                Fetch&& fetch, F&& f) {
  if constexpr (Direct)
    for_each_neighbour(g, offsets, pts, x, support2, skip, [&](uint32_t j, Float4, Vec3f, float) { f(j, fetch(j)); });
  else for_each_masked(m, i, fetch, f);
}

}  // namespace sphray
