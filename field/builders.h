// The three density-field builders as per-particle / per-voxel functors, one
// source for both backends (docs/design.md). docs/field.md describes each and
// what its counters mean. Counters are compiled in only when asked for
// (Count = true), so a timed build does not pay for them.
#pragma once

#include <cstdint>

#include "anisotropy.h"
#include "core/atomics.h"
#include "sph/mirror_walls.h"
#include "sph/params.h"
#include "volume.h"

namespace sphray {

// Per-element counters, [kNumCounters][n] element-major.
enum FieldCounter : uint32_t { kPairs = 0, kTouched = 1, kAtomics = 2, kSkipped = 3, kNumCounters = 4 };

struct CounterSink {
  uint32_t* counts;  // null when not counting
  uint32_t n;
  SPHRAY_HD SPHRAY_FORCEINLINE void put(uint32_t i, uint32_t pairs, uint32_t touched, uint32_t atomics,
                                        uint32_t skipped) const {
    counts[kPairs * n + i] = pairs;
    counts[kTouched * n + i] = touched;
    counts[kAtomics * n + i] = atomics;
    counts[kSkipped * n + i] = skipped;
  }
};

SPHRAY_HD SPHRAY_FORCEINLINE void voxel_coords(const VolumeGeom& v, uint32_t idx, int& i, int& j, int& k) {
  i = int(idx % uint32_t(v.nx));
  const uint32_t t = idx / uint32_t(v.nx);
  j = int(t % uint32_t(v.ny));
  k = int(t / uint32_t(v.ny));
}

// The voxels of the box [x0, x1] x [y0, y1] x [z0, z1] numbered 0 ..
// count - 1, x fastest (count 0 where a span is empty): the G threads of one
// particle take every G-th number (lane 0..G-1 from its own).
struct VoxelBox {
  int x0, y0, z0;
  uint32_t wx, wy, count;
  SPHRAY_HD SPHRAY_FORCEINLINE VoxelBox(int x0_, int x1, int y0_, int y1, int z0_, int z1)
      : x0(x0_), y0(y0_), z0(z0_), wx(0), wy(0), count(0) {
    if (x0_ > x1 || y0_ > y1 || z0_ > z1) return;
    wx = uint32_t(x1 - x0_ + 1);
    wy = uint32_t(y1 - y0_ + 1);
    count = wx * wy * uint32_t(z1 - z0_ + 1);
  }
  SPHRAY_HD SPHRAY_FORCEINLINE void voxel(uint32_t v, int& i, int& j, int& k) const {
    const uint32_t t = v / wx;
    i = x0 + int(v - t * wx);
    j = y0 + int(t % wy);
    k = z0 + int(t / wy);
  }
};

// Visits the voxels (i, j, k) of a box (the naive splat's), shared by the G
// threads of one particle: G = 1 is one thread per particle, G = 32 a warp
// per particle; more lanes shorten a particle's loop and even out the
// loops' lengths. Plain index math: the CPU runs the same code.
template <int G, class F>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_box_voxel(uint32_t lane, int x0, int x1, int y0, int y1, int z0, int z1,
                                                     F&& f) {
  if (G == 1) {
    for (int k = z0; k <= z1; ++k)
      for (int j = y0; j <= y1; ++j)
        for (int i = x0; i <= x1; ++i) f(i, j, k);
  } else {
    const VoxelBox box(x0, x1, y0, y1, z0, z1);
    for (uint32_t v = lane; v < box.count; v += uint32_t(G)) {
      int i, j, k;
      box.voxel(v, i, j, k);
      f(i, j, k);
    }
  }
}

// A particle's kernel as the splats see it: a sphere of radius R around the
// particle, or (Aniso) its ellipsoid (anisotropy.h) around the smoothed
// centre, whose box reaches R * half along each axis.
template <bool Aniso>
struct SplatKernel {
  Vec3f u;     // centre [voxels]
  Ellipsoid e; // Aniso only
  SplatKernel() = default;
  SPHRAY_HD SPHRAY_FORCEINLINE SplatKernel(const VolumeGeom& vol, const Float4* pos, const Float4* ell, uint32_t n,
                                           uint32_t p) {
    if (Aniso) {
      e = Ellipsoid::load(ell, n, p);
      u = e.centre;
    } else {
      u = vol.to_voxels(xyz(pos[p]));
    }
  }
  // Half-extent of the box along axis a for a sphere radius r.
  SPHRAY_HD SPHRAY_FORCEINLINE float reach(int a, float r) const {
    if (!Aniso) return r;
    return r * (a == 0 ? e.half.x : a == 1 ? e.half.y : e.half.z);
  }
  // The kernel's squared distance to the centre of voxel (i, j, k).
  SPHRAY_HD SPHRAY_FORCEINLINE float r2_at(int i, int j, int k) const {
    const float dx = float(i) + 0.5f - u.x, dy = float(j) + 0.5f - u.y, dz = float(k) + 0.5f - u.z;
    return Aniso ? e.r2(dx, dy, dz) : dx * dx + dy * dy + dz * dz;
  }
};

// naive: every particle adds its full falloff (sphere or ellipsoid) to every voxel whose
// centre lies within R (one thread per particle, one atomic add per voxel; the
// volume is zeroed before). The baseline of Yasuda et al.'s Table 1.
template <bool Count, int G, bool Aniso>
struct NaiveSplat {
  VolumeGeom vol;
  FieldShape shape;
  const Float4* pos;
  const Float4* ell;  // [3][n] ellipsoids (Aniso)
  uint32_t n;
  float* field;
  CounterSink sink;  // per thread (particle x lane)

  SPHRAY_HD void operator()(uint32_t t) const {
    const uint32_t p = t / uint32_t(G), lane = t % uint32_t(G);
    const SplatKernel<Aniso> kn(vol, pos, ell, n, p);
    const Vec3f u = kn.u;
    const float R = shape.radius, R2 = R * R;
    int x0, x1, y0, y1, z0, z1;
    voxel_span(u.x, kn.reach(0, R), kn.reach(0, R), vol.nx, x0, x1);
    voxel_span(u.y, kn.reach(1, R), kn.reach(1, R), vol.ny, y0, y1);
    voxel_span(u.z, kn.reach(2, R), kn.reach(2, R), vol.nz, z0, z1);
    uint32_t pairs = 0, adds = 0;
    for_each_box_voxel<G>(lane, x0, x1, y0, y1, z0, z1, [&](int i, int j, int k) {
      const float r2 = kn.r2_at(i, j, k);
      if (Count) ++pairs;
      if (r2 < R2) {
        atomic_add(field + vol.index(i, j, k), shape.falloff(r2));
        if (Count) ++adds;
      }
    });
    if (Count) sink.put(t, pairs, adds, adds, 0);
  }
};

// presence, before pass 1 where cells are filled whole (FieldSetup::
// mark_occupied): which of the volume's SPH cells are full. A count of
// full_count particles alone does not make a cell full: a cell of dense
// (settled or compressed) liquid holds that many while its top voxels lie
// above the surface, and filling those whole would put the surface a voxel
// above the liquid over such cells (a flat pool in terraces, docs/field.md). So a
// cell is full when it holds full_count particles and each of its six face
// neighbours holds face_count (liquid beyond every face: no free surface
// crosses the cell); a face on the grid's edge counts as covered. One thread
// per cell of the volume; the flags are indexed by the grid's cell key.
struct FullCellFlags {
  VolumeGeom vol;
  GridGeom grid;
  const uint32_t* offsets;
  uint32_t full_count, face_count;
  uint8_t* full;  // [grid.num_cells()], written for the volume's cells

  SPHRAY_HD uint32_t num_items() const {
    return uint32_t(vol.nx >> vol.refine) * uint32_t(vol.ny >> vol.refine) * uint32_t(vol.nz >> vol.refine);
  }

  SPHRAY_HD void operator()(uint32_t t) const {
    const uint32_t cnx = uint32_t(vol.nx >> vol.refine), cny = uint32_t(vol.ny >> vol.refine);
    const uint32_t x = uint32_t(vol.cell0[0]) + t % cnx, y = uint32_t(vol.cell0[1]) + (t / cnx) % cny,
                   z = uint32_t(vol.cell0[2]) + t / (cnx * cny);
    const uint32_t nx = uint32_t(grid.nx), ny = uint32_t(grid.ny), nz = uint32_t(grid.nz);
    const uint32_t row = nx, plane = nx * ny, c = z * plane + y * row + x;
    auto count = [&](uint32_t k) { return offsets[k + 1] - offsets[k]; };
    bool f = count(c) >= full_count;
    f = f && (x == 0 || count(c - 1) >= face_count) && (x + 1 == nx || count(c + 1) >= face_count);
    f = f && (y == 0 || count(c - row) >= face_count) && (y + 1 == ny || count(c + row) >= face_count);
    f = f && (z == 0 || count(c - plane) >= face_count) && (z + 1 == nz || count(c + plane) >= face_count);
    full[c] = f ? 1 : 0;
  }
};

// presence, pass 1 (coarse fill, Yasuda et al. sec. 4.2.1): every voxel reads
// its SPH cell's particle count and becomes `coarse` (just above the iso
// value) or 0; this pass also initialises the volume. With spheres at
// refine = 0 a voxel is a cell and "holds a particle" is exactly count >= 1.
// With finer voxels a cell's count no longer says which of its voxels hold
// particles (nor, with ellipsoids, whether the particle's own voxel is
// inside), so only full cells (FullCellFlags) are filled whole, with
// `full`, and pass 2 marks the occupied voxels of the others.
struct CoarseFill {
  VolumeGeom vol;
  GridGeom grid;
  const uint32_t* offsets;
  float coarse;  // value of an occupied cell (no flags)
  float full;    // value of a full cell (flags)
  // FullCellFlags where FieldSetup::mark_occupied (pass 2 follows), else null:
  // every occupied cell is `coarse`.
  const uint8_t* full_cells;
  float* field;

  // One thread per run of 2^refine voxels along x that share a cell: one
  // read and one index computation for all of them.
  SPHRAY_HD uint32_t num_items() const { return uint32_t(vol.num_voxels() >> vol.refine); }

  SPHRAY_HD void operator()(uint32_t t) const {
    const int w = 1 << vol.refine;
    const uint32_t runs = uint32_t(vol.nx) >> vol.refine;
    const int i0 = int(t % runs) * w;
    const uint32_t jk = t / runs;
    const int j = int(jk % uint32_t(vol.ny)), k = int(jk / uint32_t(vol.ny));
    const uint32_t c = vol.cell_key(grid, i0, j, k);
    const float value = full_cells ? (full_cells[c] ? full : 0.0f) : (offsets[c + 1] > offsets[c] ? coarse : 0.0f);
    float* out = field + vol.index(i0, j, k);
    for (int i = 0; i < w; ++i) out[i] = value;
  }
};

// The presence splat's extent toward side d (+x, -x, +y, -y, +z, -z) of
// particle p, from its presence there ([6][n]; null: the full radius).
SPHRAY_HD SPHRAY_FORCEINLINE float side_extent(const FieldShape& shape, const float* presence, uint32_t n, uint32_t p,
                                               uint32_t d) {
  return presence ? shape.extent(presence[d * n + p]) : shape.radius;
}

// The voxels within reach(d) of u toward each side d (+x, -x, +y, -y, +z,
// -z): the box a splat from u may touch.
template <class Reach>
SPHRAY_HD SPHRAY_FORCEINLINE void side_box(const VolumeGeom& vol, Vec3f u, const Reach& reach, int& x0, int& x1,
                                           int& y0, int& y1, int& z0, int& z1) {
  voxel_span(u.x, reach(1u), reach(0u), vol.nx, x0, x1);
  voxel_span(u.y, reach(3u), reach(2u), vol.ny, y0, y1);
  voxel_span(u.z, reach(5u), reach(4u), vol.nz, z0, z1);
}

// The presence builder's full cells (FullCellFlags, filled with the clip
// value by CoarseFill): cover() says whether every cell under a voxel box is
// full, so that a splat over that box would find every voxel saturated
// (false for an empty box, or without flags: full cells not saturated). A
// box of at most 2 x 2 x 2 cells reads their flags together.
struct FullCells {
  VolumeGeom vol;
  GridGeom grid;
  const uint8_t* flags;  // FullCellFlags, or null
  SPHRAY_HD SPHRAY_FORCEINLINE bool cover(int x0, int x1, int y0, int y1, int z0, int z1) const {
    if (!flags || x0 > x1 || y0 > y1 || z0 > z1) return false;
    const int s = vol.refine;
    const int cx0 = x0 >> s, cy0 = y0 >> s, cz0 = z0 >> s, cx1 = x1 >> s, cy1 = y1 >> s, cz1 = z1 >> s;
    if (cx1 - cx0 <= 1 && cy1 - cy0 <= 1 && cz1 - cz0 <= 1) {
      // At most 2 x 2 x 2 cells (a deep particle's box): their flags read
      // together, not one round trip after another (a cell repeats where
      // the box spans one along an axis).
      uint8_t f[8];
      SPHRAY_UNROLL
      for (int q = 0; q < 8; ++q) {
        const int cx = cx0 + (q & 1) < cx1 ? cx0 + (q & 1) : cx1;
        const int cy = cy0 + ((q >> 1) & 1) < cy1 ? cy0 + ((q >> 1) & 1) : cy1;
        const int cz = cz0 + (q >> 2) < cz1 ? cz0 + (q >> 2) : cz1;
        f[q] = flags[vol.cell_key(grid, cx << s, cy << s, cz << s)];
      }
      bool full = true;
      SPHRAY_UNROLL
      for (int q = 0; q < 8; ++q) full = full && f[q] != 0;
      return full;
    }
    for (int cz = z0 >> s; cz <= z1 >> s; ++cz)
      for (int cy = y0 >> s; cy <= y1 >> s; ++cy)
        for (int cx = x0 >> s; cx <= x1 >> s; ++cx)
          if (!flags[vol.cell_key(grid, cx << s, cy << s, cz << s)]) return false;
    return true;
  }
};

// presence, pass 2 (FieldSetup::mark_occupied): the voxel that holds a
// particle's (kernel) centre u becomes `coarse` too. A sphere's iso radius is
// at least half the voxel diagonal, so that voxel is inside; an ellipsoid may
// be thinner than a voxel, so it is marked only where the particle's own
// kernel reaches the iso value at the voxel centre (the field, a sum of such
// terms, does too). Every writer writes the same value: a plain (relaxed)
// store will do.
template <bool Aniso>
SPHRAY_HD SPHRAY_FORCEINLINE void mark_occupied(const VolumeGeom& vol, const FieldShape& shape, const SplatKernel<Aniso>& kn,
                                                float* field) {
  const Vec3f u = kn.u;
  const int i = int(std::floor(u.x)), j = int(std::floor(u.y)), k = int(std::floor(u.z));
  if (i < 0 || j < 0 || k < 0 || i >= vol.nx || j >= vol.ny || k >= vol.nz) return;
  if (Aniso && !(shape.falloff(kn.r2_at(i, j, k)) >= shape.iso)) return;
  const float coarse = shape.coarse;
  float* cell = field + vol.index(i, j, k);
  if (load_relaxed(cell) < coarse) store_relaxed(cell, coarse);  // a full cell's voxel already holds more
}

// Pass 2 for spheres: one thread per particle.
struct MarkOccupied {
  VolumeGeom vol;
  FieldShape shape;
  const Float4* pos;
  uint32_t n;
  float* field;

  SPHRAY_HD void operator()(uint32_t p) const {
    mark_occupied(vol, shape, SplatKernel<false>(vol, pos, nullptr, n, p), field);
  }
};

// The ellipsoids' pass (anisotropy.h: ComputeAnisotropy or
// AnisotropyFromSums), and for the presence builder pass 2 on the ellipsoid
// it has just computed (mark: after the coarse fill), so that the marks do
// not read the ellipsoids back in a pass of their own. With full.flags set
// (the presence builder, where the pass sums each neighbourhood itself:
// ComputeAnisotropy) it first leaves out the particles whose ellipsoid,
// whatever it turns out to be (EllipsoidBound), has its splat box (pass 3:
// extents shrunk by presence) in full cells only: their splat would add
// nothing and their mark would fall in a saturated voxel, so neither their
// neighbours' covariance nor their ellipsoid is computed, and pass 3 skips
// them on the mark they get (Ellipsoid::store_buried).
template <class Ellipsoids>
struct EllipsoidPass {
  Ellipsoids make;
  float* mark;  // the volume, or null: no marks (naive)
  FieldShape shape;
  FullCells full{};          // flags null: no particle left out (naive)
  const float* presence = nullptr;  // [6][n] or null: full extents
  EllipsoidBound bound{};

  // Item t of the pass (make's order), particle p = make.particle(t) of the view.
  SPHRAY_HD SPHRAY_FORCEINLINE bool buried(uint32_t t, uint32_t p) const {
    if (!full.flags) return false;
    int x0, x1, y0, y1, z0, z1;
    side_box(make.vol, make.vol.to_voxels(xyz(make.pos[t])),
             [&](uint32_t d) { return bound.reach(side_extent(shape, presence, make.n, p, d)); }, x0, x1, y0, y1, z0,
             z1);
    return full.cover(x0, x1, y0, y1, z0, z1);
  }

  SPHRAY_HD void operator()(uint32_t t) const {
    const uint32_t p = make.particle(t);
    if (buried(t, p)) {
      Ellipsoid::store_buried(make.out, p);
      return;
    }
    SplatKernel<true> kn;
    kn.e = make.compute(t);
    kn.e.store(make.out, make.n, p);
    if (!mark) return;
    kn.u = kn.e.centre;
    mark_occupied(make.vol, shape, kn, mark);
  }
};

// presence, pass 3 (fine splat, sec. 4.2.2-4.2.4): each particle adds its
// falloff (sphere or ellipsoid) over a box whose half-extent toward each of
// the six directions (the ellipsoid's box, scaled by extent / R) shrinks with
// its presence there (FieldShape::extent: a deep particle
// touches almost nothing, a lone one keeps the full sphere of radius R),
// skips voxels already at or above the clip (saturation) value, and leaves
// none past it (an atomic add, and a second one that takes back any
// overshoot; see below). Without presence (null) every extent is R.
template <bool Count, int G, bool Aniso>
struct PresenceSplat {
  VolumeGeom vol;
  FieldShape shape;
  const Float4* pos;
  const Float4* ell;      // [3][n] ellipsoids (Aniso)
  const float* presence;  // [6][n] (+x,-x,+y,-y,+z,-z) or null
  uint32_t n;
  float* field;
  CounterSink sink;
  // Full cells hold the clip value (CoarseFill): a splat box that lies in full
  // cells only would find every voxel saturated, so it is skipped after
  // reading the (at most 8, shared and cached) cell flags instead of its voxels.
  FullCells full;  // flags null: full cells are not saturated, no cell test

  // A thread's voxels in batches of kBatch: the batch's reads are issued
  // together, then its adds, then its take-backs, so that the thread waits
  // for each kind of round trip once per batch instead of once per voxel.
  // (A read that is stale by the time of the add only makes the add larger;
  // the take-back, from the add's own return value, keeps the exact result.
  // So the reads may come from the L1 cache (load_cached): a voxel's value
  // only grows, but for a moment between an add and its take-back, when the
  // sum has passed the clip anyway, so a stale value errs low.)
  // 4 rather than 8: 8 held 72 registers against 54 (ellipsoids), fewer
  // threads resident, and was slower at 1M and 4M on the H100 (docs/field.md).
  static constexpr int kBatch = 4;

  SPHRAY_HD void operator()(uint32_t t) const {
    const uint32_t p = t / uint32_t(G), lane = t % uint32_t(G);
    if (Aniso && Ellipsoid::is_buried(ell, p)) {  // left out by the ellipsoids' pass
      if (Count) sink.put(t, 0, 0, 0, 0);
      return;
    }
    const SplatKernel<Aniso> kn(vol, pos, ell, n, p);
    const Vec3f u = kn.u;
    const float R2 = shape.radius * shape.radius, clip = shape.clip;
    int x0, x1, y0, y1, z0, z1;
    side_box(vol, u, [&](uint32_t d) { return kn.reach(int(d / 2), side_extent(shape, presence, n, p, d)); }, x0, x1,
             y0, y1, z0, z1);
    uint32_t pairs = 0, touched = 0, atomics = 0, skipped = 0;
    if (!full.cover(x0, x1, y0, y1, z0, z1)) {
      const VoxelBox box(x0, x1, y0, y1, z0, z1);
      for (uint32_t base = lane; base < box.count; base += uint32_t(G * kBatch)) {
        float* cell[kBatch];
        float f[kBatch] = {}, seen[kBatch], add[kBatch], before[kBatch] = {};
        SPHRAY_UNROLL
        for (int b = 0; b < kBatch; ++b) {  // the reads
          const uint32_t v = base + uint32_t(b * G);
          cell[b] = nullptr;
          seen[b] = clip;
          if (v >= box.count) continue;
          int i, j, k;
          box.voxel(v, i, j, k);
          const float r2 = kn.r2_at(i, j, k);
          if (Count) ++pairs;
          if (!(r2 < R2)) continue;
          f[b] = shape.falloff(r2);
          cell[b] = field + vol.index(i, j, k);
          seen[b] = load_cached(cell[b]);
          if (Count) ++touched;
        }
        SPHRAY_UNROLL
        for (int b = 0; b < kBatch; ++b) {  // the adds
          add[b] = 0.0f;
          if (!cell[b]) continue;
          if (seen[b] >= clip) {
            if (Count) ++skipped;
            continue;
          }
          // Add at most what fills the voxel to the clip as seen; whatever a
          // concurrent add pushed past it comes off again. The final value is
          // exactly min(clip, sum) (docs/field.md has the argument), with one
          // atomic add per voxel, plus one only where the voxel saturates.
          add[b] = std::fmin(f[b], clip - seen[b]);
          before[b] = atomic_fetch_add(cell[b], add[b]);
          if (Count) ++atomics;
        }
        SPHRAY_UNROLL
        for (int b = 0; b < kBatch; ++b) {  // the take-backs
          if (!(add[b] > 0.0f)) continue;
          const float over = before[b] + add[b] - clip;
          if (over > 0.0f) {
            atomic_add(cell[b], -std::fmin(over, add[b]));
            if (Count) ++atomics;
          }
        }
      }
    }
    if (Count) sink.put(t, pairs, touched, atomics, skipped);
  }
};

// The SPH cells that the cube of half-width R around the centre (cx, cy, cz)
// of a voxel overlaps, row by row (in voxel units): fn(row, x0, x1), each
// row's cells x0..x1 one contiguous range of the sort.
template <class Fn>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_row_near(const VolumeGeom& vol, const GridGeom& grid, float cx, float cy,
                                                    float cz, float R, Fn&& fn) {
  const float per = float(1 << vol.refine);
  auto cell_of = [&](float c, int axis) { return vol.cell0[axis] + int(std::floor(c / per)); };
  const int gx0 = cell_of(cx - R, 0) < 0 ? 0 : cell_of(cx - R, 0);
  const int gx1 = cell_of(cx + R, 0) >= grid.nx ? grid.nx - 1 : cell_of(cx + R, 0);
  const int gy0 = cell_of(cy - R, 1) < 0 ? 0 : cell_of(cy - R, 1);
  const int gy1 = cell_of(cy + R, 1) >= grid.ny ? grid.ny - 1 : cell_of(cy + R, 1);
  const int gz0 = cell_of(cz - R, 2) < 0 ? 0 : cell_of(cz - R, 2);
  const int gz1 = cell_of(cz + R, 2) >= grid.nz ? grid.nz - 1 : cell_of(cz + R, 2);
  for (int z = gz0; z <= gz1; ++z)
    for (int y = gy0; y <= gy1; ++y)
      fn((uint32_t(z) * uint32_t(grid.ny) + uint32_t(y)) * uint32_t(grid.nx), uint32_t(gx0), uint32_t(gx1));
}

// gather: one thread per voxel sums the falloff of the particles stored in the
// SPH cells that its sphere of radius R overlaps; plain stores, no atomics,
// no zeroing. It computes the naive field (up to summation order).
template <bool Count>
struct GatherField {
  VolumeGeom vol;
  GridGeom grid;
  FieldShape shape;
  const uint32_t* offsets;
  const Float4* pos;
  float* field;
  CounterSink sink;

  SPHRAY_HD void operator()(uint32_t v) const {
    int i, j, k;
    voxel_coords(vol, v, i, j, k);
    const float cx = float(i) + 0.5f, cy = float(j) + 0.5f, cz = float(k) + 0.5f;
    float sum = 0.0f;
    uint32_t pairs = 0;
    for_each_row_near(vol, grid, cx, cy, cz, shape.radius, [&](uint32_t row, uint32_t x0, uint32_t x1) {
      const uint32_t end = offsets[row + x1 + 1u];
      for (uint32_t q = offsets[row + x0]; q < end; ++q) {
        const Vec3f u = vol.to_voxels(xyz(pos[q]));
        const float dx = cx - u.x, dy = cy - u.y, dz = cz - u.z;
        if (Count) ++pairs;
        sum += shape.falloff(dx * dx + dy * dy + dz * dz);
      }
    });
    field[v] = sum;
    if (Count) sink.put(v, pairs, 1, 0, 0);
  }
};

// Zhu & Bridson's surface ("Animating Sand as a Fluid", 2005), built by the
// gather builder: at each voxel centre x the particles within R give their
// weighted mean position m = sum_i k_i x_i / sum_i k_i, k_i = (1 - |x -
// x_i|^2 / R^2)^3, and phi(x) = |x - m| - r, negative inside, r the
// particle radius where the voxel sees four or more particles' worth of
// weight and a lone particle's radius (at least sqrt(3)/2 voxel) where it
// sees two or fewer (ZhuBridsonParams::radius_at). A lone
// particle is a ball of that radius; over a flat surface m follows the top
// layers, so phi moves with them continuously, and with its smooth slope it is
// resolved at any place of the surface within its voxel (a sum of
// metaballs steps from saturated to empty within a voxel there: docs/field.md).
// Stored as iso (1 - phi / (R - r)), clamped to [0, clip]: the surface is at
// iso, and the value falls to 0 where a lone particle's reach ends, so the
// field is continuous as particles enter and leave a voxel's reach
// (ZhuBridsonParams: volume.h). G threads per voxel over the particles
// sorted by a grid of cells of at least R / 2 (anisotropy_grid, as the
// ellipsoids' pass): its 25 rows around the voxel centre, culled to R;
// first, from the view grid's cell table, whether any particle lies in
// the SPH cells the voxel's reach overlaps (most voxels are far from the
// liquid: the 25 rows' table reads would cost them more than their
// particles cost the voxels near it). G = 1 except on the CUDA backend
// where a voxel's reach holds many particles (coarse voxels, field.refine 0
// or 1; zhu_bridson_group): there each lane sums every G-th candidate of
// the rows and the group's sums meet by warp shuffles; lane 0 stores.
template <bool Count, int G>
struct ZhuBridsonGather {
  static constexpr int kSpan = 2;
  static_assert(G == 1 || G == 4 || G == 8 || G == 32, "lanes per voxel: 1, 4, 8 or 32");
  VolumeGeom vol;
  GridGeom view;                 // the SPH grid
  const uint32_t* view_offsets;  // its cell table
  GridGeom grid;                 // cells of at least R / 2
  const uint32_t* fine_offsets;  // its slab table
  const Float4* pos;             // sorted by it
  FieldShape shape;
  ZhuBridsonParams zb;
  float* field;
  CounterSink sink;              // per thread (voxel x lane)
  // voxels x G. With G > 1 the launch is rounded up to whole warps, and the
  // threads past it only take part in the shuffles, so that every lane of
  // a warp reaches them (the full mask) whatever the voxel count.
  uint32_t threads;

  // The group's sum of a lane's value (every lane of the group gets it).
  SPHRAY_HD SPHRAY_FORCEINLINE static float group_sum(float value) {
#if defined(__CUDA_ARCH__)
    SPHRAY_UNROLL
    for (int d = G / 2; d > 0; d /= 2) value += __shfl_xor_sync(0xffffffffu, value, d);
#endif
    return value;  // the host runs G = 1 only (the builder refuses more)
  }

  SPHRAY_HD void operator()(uint32_t t) const {
    const bool real = t < threads;
    const uint32_t v = real ? t / uint32_t(G) : 0u, lane = t % uint32_t(G);
    int i, j, k;
    voxel_coords(vol, v, i, j, k);
    const float h = vol.voxel;
    // The voxel's centre: a voxel beyond a mirroring wall takes its image's
    // value (the others keep their centres exactly, as without the walls).
    float cx = float(i) + 0.5f, cy = float(j) + 0.5f, cz = float(k) + 0.5f;
    Vec3f x{vol.origin.x + cx * h, vol.origin.y + cy * h, vol.origin.z + cz * h};
    const bool walls = zb.walls.mirror;
    if (walls) {
      const Vec3f in = reflect_into(zb.walls.tank, zb.walls.open_top, x);
      if (in.x != x.x || in.y != x.y || in.z != x.z) {
        x = in;
        cx = (x.x - vol.origin.x) / h;
        cy = (x.y - vol.origin.y) / h;
        cz = (x.z - vol.origin.z) / h;
      }
    }
    // No particle within R: none of their images either (an image lies
    // beyond the wall that x lies inside of, farther from x than its original).
    bool any = false;
    if (real)
      for_each_row_near(vol, view, cx, cy, cz, zb.radius,
                        [&](uint32_t row, uint32_t x0, uint32_t x1) { any |= view_offsets[row + x1 + 1u] > view_offsets[row + x0]; });
    // Most voxels: nothing within reach, written at once (with G > 1 every
    // lane goes on to the shuffles, and `any` skips the rows).
    if (G == 1 && !any) {
      field[v] = 0.0f;
      if (Count) sink.put(t, 0, 1, 0, 0);
      return;
    }
    const float R = zb.radius, inv_Rw = 1.0f / (R * h);
    // Offsets of the particles (and their images) from x in units of R: their weighted mean is (m - x) / R.
    float w = 0.0f, mx = 0.0f, my = 0.0f, mz = 0.0f;
    uint32_t pairs = 0;
    auto add = [&](Vec3f p) {
      const float dx = (p.x - x.x) * inv_Rw, dy = (p.y - x.y) * inv_Rw, dz = (p.z - x.z) * inv_Rw;
      const float s = 1.0f - (dx * dx + dy * dy + dz * dz);
      if (s <= 0.0f) return;
      const float kq = s * s * s;
      w += kq;
      mx += kq * dx;
      my += kq * dy;
      mz += kq * dz;
    };
    // A particle's image across the walls within R of x is no nearer to x
    // than the particle is (x and the particle lie on the wall's inner
    // side), so x's candidates hold every particle whose image is within R:
    // one walk of the rows sums both.
    const Mirrors mirrors = walls ? mirrors_near(zb.walls.tank, zb.walls.open_top, R * h, x) : Mirrors{};
    for (int row = 0; any && row < candidate_rows<kSpan>(); ++row) {
      uint32_t begin = 0, end = 0;
      if (!candidate_row<kSpan>(grid, fine_offsets, x, row, begin, end, R * h)) continue;
      for (uint32_t q = begin + lane; q < end; q += uint32_t(G)) {
        const Vec3f p = xyz(pos[q]);
        if (Count) ++pairs;
        add(p);
        if (mirrors.axes != 0u) mirrors.images(p, [&](Vec3f image, uint32_t) { add(image); });
      }
    }
    if (G > 1) {
      w = group_sum(w);
      mx = group_sum(mx);
      my = group_sum(my);
      mz = group_sum(mz);
    }
    if (!real) return;
    if (Count) sink.put(t, pairs, lane == 0 ? 1 : 0, 0, 0);
    if (lane != 0) return;
    float f = 0.0f;
    if (w > 0.0f) {
      const float r = zb.radius_at(w);
      const float phi = R * std::sqrt(mx * mx + my * my + mz * mz) / w - r;
      f = shape.iso * (1.0f - phi / (R - r));
      f = f < 0.0f ? 0.0f : (f > shape.clip ? shape.clip : f);
    }
    field[v] = f;
  }
};

}  // namespace sphray
