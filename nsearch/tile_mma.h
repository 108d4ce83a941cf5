// The pair-mask build's tile test on the tensor cores (GPU, sm_80 and later):
// for the 32 queries of a warp against a tile of 32 candidates, the 1024
// squared distances in 8 warp-wide matrix multiply-adds (mma.sync m16n8k16,
// half inputs, float accumulation) instead of 32 compares per lane of the
// FMA test in pair_masks.h (BuildPairMask). That build is bound by issued
// instructions, nearly all of them the test, which this one issues far fewer
// of (docs/notebook/benchmarks-history.md has what it gains).
//
// With y = (x_i - O) / s and t = (x_j - O) / s (O the centre of the warp's
// bounding box, s the support radius), |y - t|^2 - reach = -2 y.t + |t|^2 + C
// with C = |y|^2 - reach is one row of A times one column of B. Half
// precision keeps 11 bits, so y, t, |t|^2 and C are each split into a half
// "hi" and the half rounding of the rest, "lo", as in the residual schemes
// that recover single precision from half-precision tensor cores (Markidis
// et al. 2018); products of halves are exact in the float accumulator, and
//   y.t = yh.th + yh.tl + yl.th (+ yl.tl, below 2^-22 |y||t|, dropped):
//   k:  0-2     3-5     6-8     9    10   11   12
//   A:  -2yh    -2yh    -2yl    1    1    Ch   Cl
//   B:  th      tl      th      t2h  t2l  1    1
// With the warp's queries within 2 s of O in each axis (checked; a warp
// spread wider, e.g. across the end of a grid row, keeps the FMA test; in
// cells of one support, as PBF's step sorts by, a warp's 32 queries lie
// along about 3.5 s of a row) and the candidates that can be neighbours
// within 1 s of a query, every term is below about 20 and the float
// accumulation errs by at most about 4e-5 of s^2 (the halves' residuals
// 2^-22 of each term, the accumulation's rounding 2^-24 of the largest
// partial sum per term), inside the relative slack of the test (BuildPairMask::kTileSlack,
// 1e-4): the test keeps every neighbour and at most a candidate a hair
// beyond, as the FMA test does (tests/test_gpu.cpp checks both against the
// CPU's lists).
//
// Layouts (PTX ISA, "Matrix Fragments for mma.m16n8k16", f16): lane = 4 g + t.
// A (16 x 16, row-major): a0 = (row g, k 2t..2t+1), a1 = (g + 8, 2t..),
// a2 = (g, 2t+8..), a3 = (g + 8, 2t+8..). B (16 x 8): b0 = (k 2t..2t+1,
// column g), b1 = (k 2t+8.., g). D (16 x 8, float): d0, d1 = (row g, columns
// 2t, 2t+1), d2, d3 = (row g + 8, the same columns). Queries are rows (two
// m-tiles of 16), candidates columns (four n-tiles of 8). Candidate q of the
// tile goes to n-tile (q >> 1) & 3, column 2 (q >> 3) + (q & 1): then lane
// (g, t) holds the results of candidates 8t .. 8t+7 for its four queries g,
// g + 8, g + 16, g + 24, shifts their signs (1: within reach) into one byte
// per query, and query i's word is the four bytes of lanes 4 (i & 7) + t,
// t = 0..3, gathered by shuffles, in candidate order.
#pragma once

#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ >= 800
#define SPHRAY_TILE_MMA 1

#include <cuda_fp16.h>

#include <cstdint>

#include "core/vec.h"

namespace sphray {

class TileMma {
 public:
  // Words of shared memory per warp (the B fragments of a tile; the A rows once).
  static constexpr int kSharedWords = 256;

  // Sets up the A fragments of the warp's 32 queries at x (one per lane; all
  // 32 lanes call it together). Returns false, for every lane, when the
  // queries spread wider than the precision above allows: keep the FMA test.
  __device__ __forceinline__ bool setup(Vec3f x, float support2, float slack, uint32_t* shared) {
    const unsigned all = 0xffffffffu;
    float lo_x = x.x, lo_y = x.y, lo_z = x.z, hi_x = x.x, hi_y = x.y, hi_z = x.z;
#pragma unroll
    for (int d = 16; d >= 1; d /= 2) {
      lo_x = fminf(lo_x, __shfl_xor_sync(all, lo_x, d));
      lo_y = fminf(lo_y, __shfl_xor_sync(all, lo_y, d));
      lo_z = fminf(lo_z, __shfl_xor_sync(all, lo_z, d));
      hi_x = fmaxf(hi_x, __shfl_xor_sync(all, hi_x, d));
      hi_y = fmaxf(hi_y, __shfl_xor_sync(all, hi_y, d));
      hi_z = fmaxf(hi_z, __shfl_xor_sync(all, hi_z, d));
    }
    inv_s_ = inv_sqrt(support2);
    const float spread = fmaxf(hi_x - lo_x, fmaxf(hi_y - lo_y, hi_z - lo_z)) * inv_s_;
    if (!(spread <= 4.0f)) return false;  // (and a NaN position)
    origin_ = {0.5f * (lo_x + hi_x), 0.5f * (lo_y + hi_y), 0.5f * (lo_z + hi_z)};
    const Vec3f y = (x - origin_) * inv_s_;
    const float reach = support2 * inv_s_ * inv_s_ * (1.0f + slack);
    float yh[3], yl[3], ch, cl;
    split(y.x, yh[0], yl[0]);
    split(y.y, yh[1], yl[1]);
    split(y.z, yh[2], yl[2]);
    split(length2(y) - reach, ch, cl);
    const uint32_t lane = threadIdx.x % 32;
    uint32_t* row = shared + lane * 8;
    row[0] = pack(-2.0f * yh[0], -2.0f * yh[1]);
    row[1] = pack(-2.0f * yh[2], -2.0f * yh[0]);
    row[2] = pack(-2.0f * yh[1], -2.0f * yh[2]);
    row[3] = pack(-2.0f * yl[0], -2.0f * yl[1]);
    row[4] = pack(-2.0f * yl[2], 1.0f);
    row[5] = pack(1.0f, ch);
    row[6] = pack(cl, 0.0f);
    row[7] = 0u;
    __syncwarp();
    const uint32_t g = lane / 4, t = lane % 4;
#pragma unroll
    for (int m = 0; m < 2; ++m) {
      a_[m][0] = shared[(16 * m + g) * 8 + t];
      a_[m][1] = shared[(16 * m + g + 8) * 8 + t];
      a_[m][2] = shared[(16 * m + g) * 8 + t + 4];
      a_[m][3] = shared[(16 * m + g + 8) * 8 + t + 4];
    }
    __syncwarp();
    return true;
  }

  // The bits of one tile for this lane's query: bit k set where candidate k
  // (pts[base + k], k < count; lane k holds it) lies within the support (and its slack). All
  // 32 lanes call it together.
  // `candidate`: pts[base + lane], loaded by the caller (ahead of time).
  __device__ __forceinline__ uint32_t bits(Vec3f candidate, uint32_t count, uint32_t* shared) const {
    const uint32_t lane = threadIdx.x % 32;
    // This lane's candidate, q = lane, as one column of B (padding: |t|^2 far beyond reach).
    uint32_t w[6];
    if (lane < count) {
      const Vec3f tv = (candidate - origin_) * inv_s_;
      float th[3], tl[3], t2h, t2l;
      split(tv.x, th[0], tl[0]);
      split(tv.y, th[1], tl[1]);
      split(tv.z, th[2], tl[2]);
      split(length2(tv), t2h, t2l);
      w[0] = pack(th[0], th[1]);
      w[1] = pack(th[2], tl[0]);
      w[2] = pack(tl[1], tl[2]);
      w[3] = pack(th[0], th[1]);
      w[4] = pack(th[2], t2h);
      w[5] = pack(t2l, 1.0f);
    } else {
      w[0] = w[1] = w[2] = w[3] = 0u;
      w[4] = pack(0.0f, 16384.0f);
      w[5] = pack(0.0f, 1.0f);
    }
    // Column g of n-tile n, stored where the lanes (g, t = 0..3) read their
    // fragments: words k/2 = t (b0) and t + 4 (b1).
    const uint32_t n = (lane >> 1) & 3u, g = ((lane >> 3) << 1) | (lane & 1u);
    uint4* frag = reinterpret_cast<uint4*>(shared);
    frag[(n * 64 + 4 * g) / 4] = make_uint4(w[0], w[1], w[2], w[3]);
    frag[(n * 64 + 32 + 4 * g) / 4] = make_uint4(w[4], w[5], pack(1.0f, 0.0f), 0u);
    __syncwarp();
    // The signs of the results shifted in, one funnel shift each, per query
    // slot 2m + h (queries 16m + 8h + lane / 4): n-tiles from the last, the
    // second column first, so that bit 2n + c ends up holding candidate
    // 8 (lane % 4) + 2n + c.
    uint32_t slot[4] = {0u, 0u, 0u, 0u};
#pragma unroll
    for (int nt = 3; nt >= 0; --nt) {
      const uint32_t b0 = shared[nt * 64 + lane], b1 = shared[nt * 64 + 32 + lane];
#pragma unroll
      for (int m = 0; m < 2; ++m) {
        float d[4];
        mma(d, a_[m], b0, b1);
        slot[2 * m] = __funnelshift_l(__float_as_uint(d[0]), __funnelshift_l(__float_as_uint(d[1]), slot[2 * m], 1), 1);
        slot[2 * m + 1] =
            __funnelshift_l(__float_as_uint(d[2]), __funnelshift_l(__float_as_uint(d[3]), slot[2 * m + 1], 1), 1);
      }
    }
    // One byte per slot (byte 2m + h).
    const uint32_t packed =
        __byte_perm(__byte_perm(slot[0], slot[1], 0x0040), __byte_perm(slot[2], slot[3], 0x0040), 0x5410);
    __syncwarp();
    // Query `lane`: byte lane / 8 of lanes 4 (lane % 8) + t, t = 0..3, in order.
    const uint32_t src = 4 * (lane % 8), byte = lane / 8, sel = byte | ((byte + 4) << 4);
    const uint32_t v0 = __shfl_sync(0xffffffffu, packed, src), v1 = __shfl_sync(0xffffffffu, packed, src + 1);
    const uint32_t v2 = __shfl_sync(0xffffffffu, packed, src + 2), v3 = __shfl_sync(0xffffffffu, packed, src + 3);
    return __byte_perm(__byte_perm(v0, v1, sel), __byte_perm(v2, v3, sel), 0x5410);
  }

 private:
  Vec3f origin_;
  float inv_s_;
  uint32_t a_[2][4];  // A fragments of the two m-tiles (queries 0-15, 16-31)

  // v = hi + lo, hi the half rounding of v, lo the half rounding of the rest.
  __device__ __forceinline__ static void split(float v, float& hi, float& lo) {
    hi = __half2float(__float2half_rn(v));
    lo = v - hi;
  }
  // Two floats as halves, `first` in the low 16 bits (the lower k index).
  __device__ __forceinline__ static uint32_t pack(float first, float second) {
    const __half2 h = __floats2half2_rn(first, second);
    return *reinterpret_cast<const uint32_t*>(&h);
  }
  __device__ __forceinline__ static void mma(float (&d)[4], const uint32_t (&a)[4], uint32_t b0, uint32_t b1) {
    asm volatile(
        "mma.sync.aligned.m16n8k16.row.col.f32.f16.f16.f32 {%0, %1, %2, %3}, {%4, %5, %6, %7}, {%8, %9}, "
        "{%10, %10, %10, %10};"
        : "=f"(d[0]), "=f"(d[1]), "=f"(d[2]), "=f"(d[3])
        : "r"(a[0]), "r"(a[1]), "r"(a[2]), "r"(a[3]), "r"(b0), "r"(b1), "f"(0.0f));
  }
};

}  // namespace sphray

#endif
