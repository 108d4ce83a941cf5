// A bounding-volume hierarchy of axis-aligned boxes over a triangle mesh (the
// "AABB tree" of Mishima et al.), built on the device as a linear BVH
// (Karras, "Maximizing Parallelism in the Construction of BVHs, Octrees, and
// k-d Trees", HPG 2012: Morton codes, one sort, every internal node in
// parallel, boxes bottom-up) and queried from host and device code alike:
// the first triangle a segment or ray crosses (particle collision, the
// raycaster), how many it crosses (inside tests), the nearest triangle to a
// point (wall particles). bvh_build.inl builds it once per backend.
#pragma once

#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/device.h"
#include "core/hd.h"
#include "core/vec.h"

namespace sphray {

// An internal node holds the boxes of both children, so that traversal tests
// a child before visiting it; a child reference with kLeafBit set is a
// triangle (its slot in the sorted triangle array).
struct alignas(16) BvhNode {
  Vec3f lo[2];
  Vec3f hi[2];
  uint32_t child[2];
  uint32_t pad[2];
};
constexpr uint32_t kLeafBit = 0x80000000u;

// A triangle as v0 and its two edges (Moeller-Trumbore); the w of each holds
// the shading normal of its corner (v0, v0 + e1, v0 + e2), octahedron-encoded
// (pack_normal): the mesh's vertex normal where it is within kCreaseCos of
// the triangle's own, else the triangle's (a cube keeps its edges).
struct alignas(16) BvhTriangle {
  Float4 v0, e1, e2;
};

// A corner's shading normal is the vertex normal only within about 40
// degrees of the triangle's normal.
constexpr float kCreaseCos = 0.766f;

// A unit vector in 32 bits (octahedral map, 16 bits per coordinate: under
// 0.01 degrees), carried as a float's bits.
SPHRAY_HD inline float pack_normal(Vec3f n) {
  const float l1 = std::fabs(n.x) + std::fabs(n.y) + std::fabs(n.z);
  float u = n.x / l1, v = n.y / l1;
  if (n.z < 0.0f) {
    const float pu = (1.0f - std::fabs(v)) * (u >= 0.0f ? 1.0f : -1.0f);
    const float pv = (1.0f - std::fabs(u)) * (v >= 0.0f ? 1.0f : -1.0f);
    u = pu;
    v = pv;
  }
  auto q = [](float x) { return uint32_t(fminf(fmaxf((x * 0.5f + 0.5f) * 65535.0f + 0.5f, 0.0f), 65535.0f)); };
  return bits_to_float(q(u) | (q(v) << 16));
}
SPHRAY_HD inline Vec3f unpack_normal(float packed) {
  const uint32_t b = float_to_bits(packed);
  const float u = float(b & 0xffffu) * (2.0f / 65535.0f) - 1.0f, v = float(b >> 16) * (2.0f / 65535.0f) - 1.0f;
  Vec3f n{u, v, 1.0f - std::fabs(u) - std::fabs(v)};
  if (n.z < 0.0f) {
    const float nu = (1.0f - std::fabs(v)) * (u >= 0.0f ? 1.0f : -1.0f);
    const float nv = (1.0f - std::fabs(u)) * (v >= 0.0f ? 1.0f : -1.0f);
    n.x = nu;
    n.y = nv;
  }
  return n * (1.0f / std::sqrt(dot(n, n)));
}

// What queries read; device pointers on CUDA, host pointers on the CPU.
struct MeshView {
  const BvhNode* nodes = nullptr;
  const BvhTriangle* tris = nullptr;
  uint32_t num_tris = 0;
  uint32_t root = 0;  // 0 (the first internal node), or kLeafBit when the mesh is one triangle
  Vec3f lo{}, hi{};   // the whole mesh's box
};

SPHRAY_HD SPHRAY_FORCEINLINE Vec3f triangle_normal(const BvhTriangle& t) {
  const Vec3f n = cross(xyz(t.e1), xyz(t.e2));
  return n * (1.0f / std::sqrt(dot(n, n)));
}

// The shading normal at a point p of the triangle: its corners' normals
// interpolated by p's barycentric coordinates (Phong), unit length.
SPHRAY_HD inline Vec3f shading_normal(const BvhTriangle& t, Vec3f p) {
  const Vec3f e1 = xyz(t.e1), e2 = xyz(t.e2), w = p - xyz(t.v0);
  const float d00 = dot(e1, e1), d01 = dot(e1, e2), d11 = dot(e2, e2), d20 = dot(w, e1), d21 = dot(w, e2);
  const float inv = 1.0f / (d00 * d11 - d01 * d01);
  const float b1 = fminf(fmaxf((d11 * d20 - d01 * d21) * inv, 0.0f), 1.0f);
  const float b2 = fminf(fmaxf((d00 * d21 - d01 * d20) * inv, 0.0f), 1.0f - b1);
  const Vec3f n = unpack_normal(t.v0.w) * (1.0f - b1 - b2) + unpack_normal(t.e1.w) * b1 + unpack_normal(t.e2.w) * b2;
  const float l2 = dot(n, n);
  return l2 > 0.0f ? n * (1.0f / std::sqrt(l2)) : triangle_normal(t);
}

// o + s d against a triangle, both faces: true with s in (0, s_max). The
// edges are widened by kEdgeSlack of the triangle (in barycentric terms), so
// that a path through a shared edge or a vertex hits at least one of the
// triangles there whatever the rounding (a particle sliding on the tank's
// floor into the bottom edge of a box standing on it, say).
constexpr float kEdgeSlack = 1e-5f;
SPHRAY_HD SPHRAY_FORCEINLINE bool hit_triangle(const BvhTriangle& t, Vec3f o, Vec3f d, float s_max, float& s) {
  const Vec3f e1 = xyz(t.e1), e2 = xyz(t.e2);
  const Vec3f p = cross(d, e2);
  const float det = dot(e1, p);
  if (det == 0.0f) return false;
  const float inv = 1.0f / det;
  const Vec3f q = o - xyz(t.v0);
  const float u = dot(q, p) * inv;
  if (u < -kEdgeSlack || u > 1.0f + kEdgeSlack) return false;
  const Vec3f r = cross(q, e1);
  const float v = dot(d, r) * inv;
  if (v < -kEdgeSlack || u + v > 1.0f + kEdgeSlack) return false;
  s = dot(e2, r) * inv;
  return s > 0.0f && s < s_max;
}

// The ray's entry into a box, with the ray's inverse direction precomputed.
SPHRAY_HD SPHRAY_FORCEINLINE bool slab(Vec3f o, Vec3f inv, Vec3f lo, Vec3f hi, float s_max, float& s_in) {
  const float tx0 = (lo.x - o.x) * inv.x, tx1 = (hi.x - o.x) * inv.x;
  const float ty0 = (lo.y - o.y) * inv.y, ty1 = (hi.y - o.y) * inv.y;
  const float tz0 = (lo.z - o.z) * inv.z, tz1 = (hi.z - o.z) * inv.z;
  const float a = fmaxf(fmaxf(fminf(tx0, tx1), fminf(ty0, ty1)), fmaxf(fminf(tz0, tz1), 0.0f));
  const float b = fminf(fminf(fmaxf(tx0, tx1), fmaxf(ty0, ty1)), fminf(fmaxf(tz0, tz1), s_max));
  s_in = a;
  return a <= b;
}

// Calls visit(slot) for every triangle whose box, widened by `pad`, the ray
// o + s d meets with s in [0, s_max], nearer boxes first; visit returns the
// new s_max (prune farther boxes) or s_max itself to see them all.
template <class Visit>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_leaf_along(const MeshView& m, Vec3f o, Vec3f d, float s_max, float pad,
                                                      Visit visit) {
  if (m.num_tris == 0) return;
  // A zero component would give 0 * inf = NaN at a box face through the
  // origin: a tiny one instead (the same side, no NaN).
  auto nz = [](float c) { return c != 0.0f ? c : 1e-30f; };
  const Vec3f inv{1.0f / nz(d.x), 1.0f / nz(d.y), 1.0f / nz(d.z)};
  const Vec3f grow{pad, pad, pad};
  float s_box;
  if (!slab(o, inv, m.lo - grow, m.hi + grow, s_max, s_box)) return;
  constexpr int kStack = 64;
  uint32_t stack[kStack];
  int top = 0;
  stack[top++] = m.root;
  while (top > 0) {
    const uint32_t ref = stack[--top];
    if (ref & kLeafBit) {
      s_max = visit(ref & ~kLeafBit);
      continue;
    }
    const BvhNode& n = m.nodes[ref];
    float s0, s1;
    const bool h0 = slab(o, inv, n.lo[0] - grow, n.hi[0] + grow, s_max, s0),
               h1 = slab(o, inv, n.lo[1] - grow, n.hi[1] + grow, s_max, s1);
    // The nearer child on top, so a first-hit search shrinks s_max early.
    if (h0 && h1 && top + 2 <= kStack) {
      if (s0 <= s1) { stack[top++] = n.child[1]; stack[top++] = n.child[0]; }
      else { stack[top++] = n.child[0]; stack[top++] = n.child[1]; }
    } else if (h0 && top < kStack) {
      stack[top++] = n.child[0];
    } else if (h1 && top < kStack) {
      stack[top++] = n.child[1];
    }
  }
}

// Calls visit(slot, s) for every triangle the ray o + s d crosses with s in
// (0, s_max), in no particular order; visit returns the new s_max.
template <class Visit>
SPHRAY_HD SPHRAY_FORCEINLINE void for_each_crossing(const MeshView& m, Vec3f o, Vec3f d, float s_max, Visit visit) {
  for_each_leaf_along(m, o, d, s_max, 0.0f, [&](uint32_t slot) {
    float s;
    return hit_triangle(m.tris[slot], o, d, s_max, s) ? (s_max = visit(slot, s)) : s_max;
  });
}

// The nearest crossing of o + s d with s in (0, s_max): its s and slot.
SPHRAY_HD SPHRAY_FORCEINLINE bool first_hit(const MeshView& m, Vec3f o, Vec3f d, float s_max, float& s_hit,
                                             uint32_t& slot_hit) {
  bool any = false;
  for_each_crossing(m, o, d, s_max, [&](uint32_t slot, float s) {
    any = true;
    s_hit = s;
    slot_hit = slot;
    return s;
  });
  return any;
}

// How many triangles the ray o + s d (s > 0) crosses.
SPHRAY_HD SPHRAY_FORCEINLINE uint32_t count_crossings(const MeshView& m, Vec3f o, Vec3f d) {
  uint32_t n = 0;
  for_each_crossing(m, o, d, 3.0e38f, [&](uint32_t, float) {
    ++n;
    return 3.0e38f;
  });
  return n;
}

// The point of a triangle nearest to p (Ericson, Real-Time Collision
// Detection, 2005, sec. 5.1.5).
SPHRAY_HD inline Vec3f closest_on_triangle(const BvhTriangle& t, Vec3f p) {
  const Vec3f a = xyz(t.v0), ab = xyz(t.e1), ac = xyz(t.e2);
  const Vec3f ap = p - a;
  const float d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3f bp = ap - ab;
  const float d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return a + ab;
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Vec3f cp = ap - ac;
  const float d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return a + ac;
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return a + ab + (ac - ab) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const float denom = 1.0f / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

SPHRAY_HD SPHRAY_FORCEINLINE float box_distance2(Vec3f p, Vec3f lo, Vec3f hi) {
  const float dx = fmaxf(fmaxf(lo.x - p.x, p.x - hi.x), 0.0f), dy = fmaxf(fmaxf(lo.y - p.y, p.y - hi.y), 0.0f),
              dz = fmaxf(fmaxf(lo.z - p.z, p.z - hi.z), 0.0f);
  return dx * dx + dy * dy + dz * dz;
}

// The squared distance from p to the mesh if below r2_max (else r2_max), and
// the nearest triangle's slot.
SPHRAY_HD inline float nearest_distance2(const MeshView& m, Vec3f p, float r2_max, uint32_t& slot_near) {
  if (m.num_tris == 0 || box_distance2(p, m.lo, m.hi) >= r2_max) return r2_max;
  constexpr int kStack = 64;
  uint32_t stack[kStack];
  int top = 0;
  stack[top++] = m.root;
  float best = r2_max;
  while (top > 0) {
    const uint32_t ref = stack[--top];
    if (ref & kLeafBit) {
      const uint32_t slot = ref & ~kLeafBit;
      const Vec3f q = closest_on_triangle(m.tris[slot], p) - p;
      const float d2 = dot(q, q);
      if (d2 < best) { best = d2; slot_near = slot; }
      continue;
    }
    const BvhNode& n = m.nodes[ref];
    const float a = box_distance2(p, n.lo[0], n.hi[0]), b = box_distance2(p, n.lo[1], n.hi[1]);
    if (a < best && b < best && top + 2 <= kStack) {
      if (a <= b) { stack[top++] = n.child[1]; stack[top++] = n.child[0]; }
      else { stack[top++] = n.child[0]; stack[top++] = n.child[1]; }
    } else if (a < best && top < kStack) {
      stack[top++] = n.child[0];
    } else if (b < best && top < kStack) {
      stack[top++] = n.child[1];
    }
  }
  return best;
}

// The tree on one backend. Built at construction from world vertices and
// triangles; refit() takes new positions of the same vertices (a deforming
// or moving mesh) and recomputes the boxes bottom-up, keeping the topology.
class Bvh {
 public:
  virtual ~Bvh() = default;
  virtual Backend backend() const = 0;
  virtual MeshView view() const = 0;
  virtual void refit(const std::vector<Vec3f>& vertices) = 0;
  // Device milliseconds of the last build (Morton codes, sort, nodes, boxes)
  // or refit (triangles, boxes), excluding the upload.
  virtual double last_ms() const = 0;
  // The triangle's index in the input of the triangle at a sorted slot.
  virtual std::vector<uint32_t> input_order() const = 0;
};

std::unique_ptr<Bvh> make_cpu_bvh(const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices);
std::unique_ptr<Bvh> make_cuda_bvh(const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices);
std::unique_ptr<Bvh> make_bvh(Backend b, const std::vector<Vec3f>& vertices, const std::vector<uint32_t>& indices);

}  // namespace sphray
