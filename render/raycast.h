// The raycaster, once for both backends: one ray per pixel through the
// density volume (field/volume.h), to the iso-surface and through it.
//
// All tracing is in voxel units (voxel centres at integer + 0.5, the frame of
// VolumeGeom::to_voxels): the field is sampled there and the march step is a
// fraction of a voxel. Per ray (docs/rendering.md has the reasoning):
//  1. clip to the volume box; march with a step of at most half a voxel,
//     jumping over bricks the surface cannot cross (occupancy below);
//  2. at a sign change of f - iso, refine between the last two samples: linear
//     interpolation, then secant (regula falsi) steps that keep the bracket;
//  3. normal from central differences of the field one voxel each way;
//  4. split with Schlick's Fresnel (Schlick 1994) into a reflected and a
//     refracted (Snell, index `ior`) branch; a ray that cannot leave (total
//     internal reflection) is reflected whole. Without `reflections` the
//     reflected branch takes the environment and the refracted one is
//     followed; with them the stronger is followed and the weaker waits,
//     traced after the first path (strongest first) within a budget of
//     further interfaces per pixel;
//  5. repeat up to `interfaces` interfaces along each path; Beer-Lambert
//     absorption on every segment inside the liquid, the absorbed share
//     replaced by the liquid's `tint`; a path's last ray takes the environment;
//  6. an obstacle (MeshHits) that a segment meets before any interface ends
//     the path there, opaque and matte: seen through the liquid, it is
//     refracted and absorbed like the floor.
// Every contribution is weight x colour (environment or tint), and the
// weights of one pixel sum to exactly 1: tests check it.
// The optics are in optics.h, the camera and the surroundings in environment.h.
#pragma once

#include <cmath>
#include <cstdint>

#include "core/hd.h"
#include "core/vec.h"
#include "environment.h"
#include "field/volume.h"
#include "optics.h"
#include "sph/obstacles.h"

namespace sphray {

// Trilinear field lookup between voxel centres; zero outside the volume.
struct TrilinearField {
  const float* f;
  int nx, ny, nz;

  SPHRAY_HD SPHRAY_FORCEINLINE float at(int i, int j, int k) const {
    if (i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz) return 0.0f;
    return f[(size_t(k) * size_t(ny) + size_t(j)) * size_t(nx) + size_t(i)];
  }
  SPHRAY_HD SPHRAY_FORCEINLINE float operator()(Vec3f u) const {
    const float x = u.x - 0.5f, y = u.y - 0.5f, z = u.z - 0.5f;
    const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    const int i = int(fx), j = int(fy), k = int(fz);
    const float a = x - fx, b = y - fy, c = z - fz;
    const float c00 = at(i, j, k) * (1 - a) + at(i + 1, j, k) * a;
    const float c10 = at(i, j + 1, k) * (1 - a) + at(i + 1, j + 1, k) * a;
    const float c01 = at(i, j, k + 1) * (1 - a) + at(i + 1, j, k + 1) * a;
    const float c11 = at(i, j + 1, k + 1) * (1 - a) + at(i + 1, j + 1, k + 1) * a;
    return (c00 * (1 - b) + c10 * b) * (1 - c) + (c01 * (1 - b) + c11 * b) * c;
  }
};

// Outward unit normal (toward lower field) at u: central differences of the
// field one voxel each way; zero where it is flat. On the trilinear field
// that is the grid's central differences at the voxel centres, interpolated
// trilinearly (the usual gradient of volume rendering): it varies smoothly
// across voxel faces, where the trilinear field's own gradient (half a voxel
// each way) jumps, which shows a coarse field's voxels in the shading
// (docs/rendering.md, "Per ray").
template <class Field>
SPHRAY_HD SPHRAY_FORCEINLINE Vec3f field_normal(const Field& field, Vec3f u) {
  const float h = 1.0f;
  const Vec3f gr{field(u + Vec3f{h, 0, 0}) - field(u - Vec3f{h, 0, 0}),
                 field(u + Vec3f{0, h, 0}) - field(u - Vec3f{0, h, 0}),
                 field(u + Vec3f{0, 0, h}) - field(u - Vec3f{0, 0, h})};
  const float l2 = dot(gr, gr);
  if (!(l2 > 0.0f)) return Vec3f{0, 0, 0};
  return gr * (-1.0f / std::sqrt(l2));
}

// Which bricks of the volume the iso-surface cannot cross. The trilinear
// field anywhere in a brick lies between the smallest and the largest of the
// voxels within one voxel of it: where all of those are below iso the brick
// holds only air, where all are at or above it only liquid. A ray outside the
// liquid crosses an air brick, and one inside crosses a liquid brick, in one
// jump.
struct Occupancy {
  static constexpr uint8_t kMayCross = 0, kAir = 1, kLiquid = 2;
  const uint8_t* occ;  // per brick, x fastest; null: no skipping
  int cx, cy, cz;      // bricks per axis
  int cell;            // voxels per brick edge

  // True where the ray at u, inside the liquid or not, meets no crossing in this brick.
  SPHRAY_HD SPHRAY_FORCEINLINE bool skip_at(Vec3f u, bool inside) const {
    if (!occ) return false;
    const int i = int(std::floor(u.x)) / cell, j = int(std::floor(u.y)) / cell, k = int(std::floor(u.z)) / cell;
    if (u.x < 0.0f || u.y < 0.0f || u.z < 0.0f || i >= cx || j >= cy || k >= cz) return !inside;  // f = 0 out there
    return occ[(size_t(k) * size_t(cy) + size_t(j)) * size_t(cx) + size_t(i)] == (inside ? kLiquid : kAir);
  }
  // Distance along d from u to the far side of u's brick.
  SPHRAY_HD SPHRAY_FORCEINLINE float cell_exit(Vec3f u, Vec3f d) const {
    const float c = float(cell);
    const float uu[3] = {u.x, u.y, u.z}, dd[3] = {d.x, d.y, d.z};
    float t = 1e30f;
    for (int k = 0; k < 3; ++k) {
      if (dd[k] == 0.0f) continue;
      const float base = std::floor(uu[k] / c) * c;
      const float wall = dd[k] > 0.0f ? base + c : base;
      const float tk = (wall - uu[k]) / dd[k];
      t = tk < t ? tk : t;
    }
    return t;
  }
};

// The per-brick classification: one thread per brick, over the voxels within
// one voxel of it (outside the volume the field is 0).
struct BuildOccupancy {
  const float* f;
  int nx, ny, nz;
  int cell;  // voxels per brick edge
  float iso;
  uint8_t* occ;

  SPHRAY_HD void operator()(uint32_t c) const {
    const int cx = (nx + cell - 1) / cell, cy = (ny + cell - 1) / cell;
    const int bi = int(c % uint32_t(cx)), bj = int((c / uint32_t(cx)) % uint32_t(cy)), bk = int(c / uint32_t(cx * cy));
    bool below = true, above = true;
    for (int k = bk * cell - 1; k <= (bk + 1) * cell && (below || above); ++k)
      for (int j = bj * cell - 1; j <= (bj + 1) * cell; ++j)
        for (int i = bi * cell - 1; i <= (bi + 1) * cell; ++i) {
          const bool in = i >= 0 && j >= 0 && k >= 0 && i < nx && j < ny && k < nz;
          const float v = in ? f[(size_t(k) * size_t(ny) + size_t(j)) * size_t(nx) + size_t(i)] : 0.0f;
          below = below && v < iso;
          above = above && v >= iso;
        }
    occ[c] = below ? Occupancy::kAir : (above ? Occupancy::kLiquid : Occupancy::kMayCross);
  }
};

// The slice method (Mishima et al.): the camera's rays sample the field
// where they cross planes normal to the view direction, `spacing` voxels
// apart (at depths z0 + k spacing from the eye), and take the crossing from
// the linear interpolation between two slices. Spacing 0: the ray march.
struct SlicePlanes {
  float spacing = 0.0f;
  Vec3f eye{0, 0, 0}, forward{0, 0, 1};  // voxel frame
  float z0 = 0.0f;

  // Along unit d from p (a camera ray: dot(d, forward) > 0): the distance
  // between two planes, and from p to the next plane, in (0, step].
  SPHRAY_HD SPHRAY_FORCEINLINE void along(Vec3f p, Vec3f d, float& first, float& step) const {
    const float c = dot(d, forward);
    step = spacing / c;
    const float z = dot(p - eye, forward);
    first = (z0 + (std::floor((z - z0) / spacing) + 1.0f) * spacing - z) / c;
  }
};

struct TraceSettings {
  float iso;
  float step;        // march step [voxels], at most 0.5
  int interfaces;    // 1 .. 8: interfaces along any one path
  float ior;         // liquid / air
  Rgb absorption;    // Beer-Lambert coefficient per voxel of path
  int secant_steps;  // after the linear interpolation
  // The reflected branch: false sends it to the environment in its
  // direction; true traces it too: the stronger branch of each interface is
  // followed first, the other waits; the waiting branches, strongest first,
  // share `budget` interfaces per pixel beyond those of the first path; a
  // branch weaker than `min_weight` (every channel) takes the environment.
  bool reflections = false;
  int budget = 8;
  float min_weight = 0.0f;
  Rgb tint{0, 0, 0};  // what the liquid scatters toward the eye where it absorbs (deep water's colour)
  SlicePlanes slices{};  // spacing > 0: camera rays sample on these planes (then step = spacing, no secant)
};

// The scene's obstacles as the tracer meets them: opaque, matte surfaces lit
// by the sun and the sky, hit through their BVHs (mesh/bvh.h) in world
// coordinates (voxel u is world origin + u voxel); a moving one in its pose
// at the render's time (`pose`, from its Motion), the ray taken into its frame.
struct MeshHits {
  Obstacles obstacles;  // count 0: none
  Vec3f origin{0, 0, 0};
  float voxel = 1.0f;
  RigidFrame pose[kMaxObstacles];  // of the moving ones
  Rgb colour{0.72f, 0.70f, 0.66f};

  // The poses at `time` [s].
  void at_time(float time) {
    for (uint32_t k = 0; k < obstacles.count; ++k) pose[k] = obstacles.motion[k].at(time);
  }

  // The nearest mesh along p + t d (voxel units) with t < t_max: its t, and
  // the shading normal there (mesh/bvh.h, shading_normal) on the side the
  // ray comes from; t_max when none.
  SPHRAY_HD float hit(Vec3f p, Vec3f d, float t_max, Vec3f& n) const {
    if (obstacles.count == 0) return t_max;
    const Vec3f w = origin + p * voxel;
    float best = t_max * voxel;
    bool any = false;
    Vec3f face{0, 0, 1};
    for (uint32_t k = 0; k < obstacles.count; ++k) {
      const bool moves = obstacles.motion[k].moves();
      const Vec3f o = moves ? pose[k].to_body(w) : w, db = moves ? pose[k].dir_to_body(d) : d;
      float s;
      uint32_t slot;
      if (first_hit(obstacles.mesh[k], o, db, best, s, slot)) {
        best = s;
        const BvhTriangle& t = obstacles.mesh[k].tris[slot];
        face = triangle_normal(t);
        n = shading_normal(t, o + s * db);
        if (moves) {
          face = pose[k].dir_to_world(face);
          n = pose[k].dir_to_world(n);
        }
        any = true;
      }
    }
    if (!any) return t_max;
    // The side comes from the triangle itself; a shading normal that turns
    // away from the ray there (a grazing ray near a rounded edge) gives way
    // to the triangle's.
    if (dot(face, d) > 0.0f) {
      face = -face;
      n = -n;
    }
    if (dot(n, d) >= 0.0f) n = face;
    return best / voxel;
  }
  // Lambert under the sun, with the sky's light from above as the ambient part.
  SPHRAY_HD Rgb shade(Vec3f n, Vec3f sun) const {
    const float sunlit = dot(n, sun) > 0.0f ? dot(n, sun) : 0.0f;
    return colour * (0.35f + 0.15f * (n.z > 0.0f ? n.z : 0.0f) + 0.55f * sunlit);
  }
};

// A scene without obstacles: the tracer's mesh tests compiled away. Carried
// unused, MeshHits took the raycast kernel from 84 to 106 registers on the
// GPU, and every frame without obstacles rendered about 20% slower (125k
// dam break, H100; docs/rendering.md).
struct NoMeshes {
  SPHRAY_HD float hit(Vec3f, Vec3f, float t_max, Vec3f&) const { return t_max; }
  SPHRAY_HD Rgb shade(Vec3f, Vec3f) const { return {0, 0, 0}; }
};

// What a test may watch (the renderer passes NoTrace: compiled away).
struct NoTrace {
  SPHRAY_HD void segment(Vec3f, Vec3f, bool) const {}
  SPHRAY_HD void interface(Vec3f, Vec3f, Vec3f, bool, float) const {}
  SPHRAY_HD void contribution(Rgb) const {}
};

// Pending: how many branches may wait at once (the weakest take the
// environment beyond that). Meshes: MeshHits, or NoMeshes where the scene has
// no obstacles.
template <class Field, int Pending = 16, class Meshes = MeshHits>
struct Tracer {
  Field field;
  Occupancy occupancy;
  Vec3f box_hi;  // the volume box is [0, box_hi] in voxels
  Environment env;
  TraceSettings ts;
  Meshes meshes{};

  // March from o along d for at most t_max, looking for f crossing iso in
  // the direction that leaves the current side (inside: f >= iso). Returns
  // the refined distance, or -1 when no crossing comes before t_max.
  // `camera`: o + t d is a camera ray (samples on the slice planes, if any).
  SPHRAY_HD float find_crossing(Vec3f o, Vec3f d, float t_max, bool inside, bool camera = false) const {
    const float iso = ts.iso;
    float t = 0.0f;
    float g = field(o) - iso;
    // On slices the samples lie at t = phase + j step (the planes); the march
    // samples t = j step.
    float phase = 0.0f, step = ts.step, plane = -1.0f;  // the plane sampled last (-1: the start, before plane 0)
    const bool planes = camera && ts.slices.spacing > 0.0f;
    if (planes) ts.slices.along(o, d, phase, step);
    // `inside` is what the last interface decided, not the sign of g here: a
    // ray that starts on the surface looks for the next crossing out of its state.
    while (t < t_max) {
      if (occupancy.skip_at(o + d * t, inside)) {
        t += occupancy.cell_exit(o + d * t, d) + 1e-3f;
        if (planes) {  // on to the next slice
          plane = std::ceil((t - phase) / step);
          t = phase + plane * step;
        }
        if (t >= t_max) return -1.0f;
        g = field(o + d * t) - iso;
        continue;
      }
      float tn = planes ? phase + (plane + 1.0f) * step : t + step;
      if (tn > t_max) tn = t_max;
      const float gn = field(o + d * tn) - iso;
      const bool crossed = inside ? gn < 0.0f : gn >= 0.0f;
      if (crossed) {
        float ta = t, ga = g, tb = tn, gb = gn;
        // No sign change: the ray started already across (its origin lies on
        // the surface within the hit's accuracy, or a sheet thinner than a
        // step): the crossing is at the start.
        if ((ga >= 0.0f) == (gb >= 0.0f)) return ta;
        // linear interpolation between the two samples, then regula falsi
        float tm = ga != gb ? ta + (tb - ta) * (ga / (ga - gb)) : tb;
        for (int s = 0; s < ts.secant_steps; ++s) {
          const float gm = field(o + d * tm) - iso;
          if ((gm >= 0.0f) == (ga >= 0.0f)) { ta = tm; ga = gm; }
          else { tb = tm; gb = gm; }
          if (ga == gb) break;
          tm = ta + (tb - ta) * (ga / (ga - gb));
        }
        return tm;
      }
      t = tn;
      g = gn;
      plane += 1.0f;
    }
    return -1.0f;
  }

  // Outward normal (toward lower field) at u.
  SPHRAY_HD Vec3f normal(Vec3f u) const { return field_normal(field, u); }

  // The colour seen along the ray o + t d (o, d in voxel units, d unit).
  template <class Watch = NoTrace>
  SPHRAY_HD Rgb trace(Vec3f o, Vec3f d, const Watch& watch = Watch{}) const {
    Vec3f p, entry_n;
    bool on_face;
    if (!enter(o, d, p, entry_n, on_face)) {
      watch.contribution(Rgb{1, 1, 1});
      return env(o, d);
    }
    Rgb colour{0, 0, 0};
    Waiting pending;
    int budget = ts.interfaces;  // the first path's; the branches then share ts.budget
    Branch b{p, d, Rgb{1, 1, 1}, field(p) >= ts.iso, 0};
    if (b.inside && on_face) {
      // The liquid touches the face it enters through (the tank's glass):
      // an interface with the face's normal, not the field's.
      b.inside = false;
      interface_at(b, entry_n, budget, colour, pending, watch);
    }
    follow(b, o, budget, colour, pending, watch);
    budget = ts.budget;
    while (pending.n > 0) {
      b = pending.take(pending.strongest());
      follow(b, o, budget, colour, pending, watch);
    }
    return colour;
  }

 private:
  struct Branch {
    Vec3f p, d;
    Rgb w;        // the share of the pixel this branch carries
    bool inside;  // in the liquid
    int k;        // interfaces met along this path
  };
  SPHRAY_HD static float share(const Branch& b) { return b.w.r + b.w.g + b.w.b; }
  // The branches waiting to be traced, strongest first: the budget goes
  // where the pixel's weight is.
  struct Waiting {
    Branch item[Pending];
    int n = 0;
    SPHRAY_HD int strongest() const {
      int best = 0;
      for (int i = 1; i < n; ++i) best = share(item[i]) > share(item[best]) ? i : best;
      return best;
    }
    SPHRAY_HD int weakest() const {
      int worst = 0;
      for (int i = 1; i < n; ++i) worst = share(item[i]) < share(item[worst]) ? i : worst;
      return worst;
    }
    SPHRAY_HD Branch take(int i) {
      const Branch b = item[i];
      item[i] = item[--n];
      return b;
    }
  };

  // Follow one branch to its end (the environment, the floor, a wall or an obstacle),
  // keeping the weaker branch of each interface in `pending`.
  template <class Watch>
  SPHRAY_HD void follow(Branch& b, Vec3f o, int& budget, Rgb& colour, Waiting& pending, const Watch& watch) const {
    Vec3f& p = b.p;
    const Vec3f& d = b.d;
    bool stopped = false;  // on the floor or an opaque wall (wall_face)
    bool on_mesh = false;  // on an obstacle, whose normal is mesh_n
    Vec3f mesh_n{0, 0, 1};
    int wall_face = 4;
    for (; b.k < ts.interfaces && budget > 0 && !stopped && !on_mesh;) {
      float b0, b1;
      ray_box(p, d, Vec3f{0, 0, 0}, box_hi, b0, b1);
      const float t_box = b1 > 0.0f ? b1 : 0.0f;
      // The tank face the ray would leave through: an opaque one stops it; past
      // a glass one there is no liquid; the top lets it go on.
      float t_wall = 1e30f, t_glass = 1e30f;
      int face = 5;
      if (env.in_tank(p)) {
        float te;
        face = env.exit_face(p, d, te);
        if (env.opaque(face)) t_wall = te;
        else if (face < 4) t_glass = te;
      }
      float t_max = t_wall < t_box ? t_wall : t_box;
      t_max = t_glass < t_max ? t_glass : t_max;
      float th = find_crossing(p, d, t_max, b.inside, b.k == 0);
      // An obstacle before the crossing (or before the end) ends the path
      // there; searched after the march, within what it found, so that most
      // rays test a short segment against the obstacles' boxes.
      const float t_mesh = meshes.hit(p, d, th >= 0.0f ? th : t_max, mesh_n);
      const bool mesh_first = t_mesh < (th >= 0.0f ? th : t_max);
      if (mesh_first) {
        th = -1.0f;
        t_max = t_mesh;
      }
      const float len = th >= 0.0f ? th : t_max;
      watch.segment(p, p + d * len, b.inside);
      if (b.inside) absorb(b.w, len, colour, watch);
      if (th < 0.0f) {
        if (mesh_first) {
          p = p + d * t_mesh;
          on_mesh = true;
          break;
        }
        if (t_wall <= t_box && t_wall <= t_glass) {  // the tank stops the ray: the environment at the wall
          p = p + d * t_wall;
          wall_face = face;
          stopped = true;
          break;
        }
        if (t_glass < t_box) {  // at the glass: out of the liquid through it, or already in air
          p = p + d * t_glass;
          if (!b.inside) break;
          interface_at(b, face_normal(face), budget, colour, pending, watch);
          if (!b.inside) break;  // refracted out of the tank: nothing more to meet
          continue;              // reflected back into the liquid
        }
        if (!b.inside) break;  // left the volume: the environment
        // still inside at the box: leave through the tank's glass
        p = p + d * t_max;
        interface_at(b, box_face_normal(p), budget, colour, pending, watch);
        continue;
      }
      p = p + d * th;
      Vec3f n = normal(p);
      if (n.x == 0.0f && n.y == 0.0f && n.z == 0.0f) n = -d;
      interface_at(b, n, budget, colour, pending, watch);
    }
    watch.contribution(b.w);
    // A ray that met no interface looks at the environment from its own
    // origin o (the volume box reaches below the floor, where the ground
    // would otherwise be seen from underneath). Branches start at one.
    if (on_mesh) colour = colour + b.w * meshes.shade(mesh_n, env.sun);
    else if (stopped) colour = colour + b.w * env.surface(wall_face, p, d);
    else colour = colour + b.w * env(b.k == 0 ? o : p, d);
  }

  // Where the ray o + t d starts looking for liquid: on the volume box (or at
  // o inside it) and within the tank's walls. The liquid stays within them:
  // a ray that starts in the volume's margin goes on to where it enters them
  // (through glass: an opaque wall or the floor seen from outside is the
  // environment's). False when the ray can meet no liquid. `on_face`: p lies
  // on a face the ray entered through, whose normal is `entry_n`.
  SPHRAY_HD SPHRAY_FORCEINLINE bool enter(Vec3f o, Vec3f d, Vec3f& p, Vec3f& entry_n, bool& on_face) const {
    float t0, t1;
    if (!ray_box(o, d, Vec3f{0, 0, 0}, box_hi, t0, t1)) return false;
    p = t0 > 0.0f ? o + d * t0 : o;
    entry_n = box_face_normal(p);
    on_face = t0 > 0.0f;
    if (env.within_walls(p)) return true;
    float e0, e1;
    const Vec3f hi{env.tank_hi.x, env.tank_hi.y, box_hi.z + 1.0f};
    if (!ray_box(p, d, env.tank_lo, hi, e0, e1) || e1 <= 0.0f) return false;
    p = p + d * (e0 > 0.0f ? e0 : 0.0f);
    const int face = nearest_face(p, env.tank_lo, env.tank_hi, 5);
    if (face < 4 && env.opaque(face)) return false;  // an opaque wall from outside: no liquid seen through it
    entry_n = face_normal(face);
    on_face = true;
    return true;
  }

  SPHRAY_HD Vec3f box_face_normal(Vec3f p) const { return face_normal(nearest_face(p, Vec3f{0, 0, 0}, box_hi)); }

  // Beer-Lambert over len voxels of liquid; what is absorbed is replaced by
  // the tint (light the liquid scatters toward the eye), so the weights of a
  // pixel still sum to 1.
  template <class Watch>
  SPHRAY_HD void absorb(Rgb& w, float len, Rgb& colour, const Watch& watch) const {
    const Rgb T{std::exp(-ts.absorption.r * len), std::exp(-ts.absorption.g * len), std::exp(-ts.absorption.b * len)};
    const Rgb lost = w * Rgb{1.0f - T.r, 1.0f - T.g, 1.0f - T.b};
    watch.contribution(lost);
    colour = colour + lost * ts.tint;
    w = w * T;
  }

  // One interface at b.p with outward normal n_out (one of the path's
  // interfaces and of the `budget`), split with Schlick's Fresnel term. Total internal reflection keeps everything inside. Else
  // without `reflections` the reflected part takes the environment and the
  // refracted part goes on; with them the stronger part goes on and the
  // weaker waits in `pending` (or takes the environment when it is weaker
  // than min_weight or could meet no further interface; when every slot is
  // taken, the weaker of it and the weakest waiting branch does).
  template <class Watch>
  SPHRAY_HD void interface_at(Branch& b, Vec3f n_out, int& budget, Rgb& colour, Waiting& pending,
                              const Watch& watch) const {
    const Vec3f p = b.p, d = b.d;
    const Vec3f n = dot(n_out, d) < 0.0f ? n_out : -n_out;  // facing the incoming ray
    const float n1 = b.inside ? ts.ior : 1.0f, n2 = b.inside ? 1.0f : ts.ior;
    const float cos_i = -dot(n, d);
    Vec3f r;
    float cos_t;
    const Vec3f refl = reflect(d, n);
    ++b.k;
    --budget;
    if (!refract(d, n, n1 / n2, r, cos_t)) {  // total internal reflection
      watch.interface(p, n, refl, true, 1.0f);
      b.d = refl;
      return;
    }
    r = normalized(r);
    const float F = schlick(n1, n2, n1 <= n2 ? cos_i : cos_t);
    watch.interface(p, n, r, false, F);
    const bool go_reflected = ts.reflections && F > 0.5f;
    Branch weak = b;  // the part not followed
    if (go_reflected) {
      weak.w = b.w * (1.0f - F);
      weak.d = r;
      weak.inside = !b.inside;
      b.w = b.w * F;
      b.d = refl;
    } else {
      weak.w = b.w * F;
      weak.d = refl;
      b.w = b.w * (1.0f - F);
      b.d = r;
      b.inside = !b.inside;
    }
    const bool keep = ts.reflections && weak.k < ts.interfaces &&
                      (weak.w.r >= ts.min_weight || weak.w.g >= ts.min_weight || weak.w.b >= ts.min_weight);
    if (keep) {
      if (pending.n < Pending) {
        pending.item[pending.n++] = weak;
        return;
      }
      const int i = pending.weakest();  // full: the weaker of it and the weakest waiting ends here
      if (share(pending.item[i]) < share(weak)) {
        const Branch out = pending.take(i);
        pending.item[pending.n++] = weak;
        weak = out;
      }
    }
    watch.contribution(weak.w);
    colour = colour + weak.w * env(weak.p, weak.d);
  }
};

// sRGB-ish encoding of a linear colour to 8 bits (gamma 2.2, clamped).
SPHRAY_HD SPHRAY_FORCEINLINE uint32_t encode_rgba8(Rgb c) {
  auto q = [](float v) {
    v = v < 0.0f ? 0.0f : (v > 1.0f ? 1.0f : v);
    return uint32_t(std::pow(v, 1.0f / 2.2f) * 255.0f + 0.5f);
  };
  return q(c.r) | (q(c.g) << 8) | (q(c.b) << 16) | (255u << 24);
}

// One thread per pixel, in 8 x 8 tiles (neighbouring threads trace
// neighbouring rays: coherent branches and field reads): camera ray (world)
// to voxel units, trace, encode.
struct PixelTiles {
  static constexpr int kTile = 8;
  int width, height;
  SPHRAY_HD SPHRAY_FORCEINLINE int tiles_x() const { return (width + kTile - 1) / kTile; }
  SPHRAY_HD SPHRAY_FORCEINLINE uint32_t items() const {
    return uint32_t(tiles_x()) * uint32_t((height + kTile - 1) / kTile) * uint32_t(kTile * kTile);
  }
  // Pixel of item idx; false outside the image (the last row and column of tiles).
  SPHRAY_HD SPHRAY_FORCEINLINE bool pixel(uint32_t idx, int& x, int& y) const {
    const uint32_t tile = idx / uint32_t(kTile * kTile), in = idx % uint32_t(kTile * kTile);
    x = int(tile % uint32_t(tiles_x())) * kTile + int(in % kTile);
    y = int(tile / uint32_t(tiles_x())) * kTile + int(in / kTile);
    return x < width && y < height;
  }
};

template <class Field, class Meshes>
struct RaycastPixels {
  Camera cam;
  Tracer<Field, 16, Meshes> tracer;
  Vec3f origin;  // volume origin [m]
  float inv_voxel;
  uint32_t* rgba;  // width x height, row 0 at the top

  SPHRAY_HD void operator()(uint32_t idx) const {
    int x, y;
    if (!PixelTiles{cam.width, cam.height}.pixel(idx, x, y)) return;
    const Vec3f d = cam.direction(float(x) + 0.5f, float(y) + 0.5f);
    const Vec3f o = (cam.eye - origin) * inv_voxel;
    rgba[size_t(y) * size_t(cam.width) + size_t(x)] = encode_rgba8(tracer.trace(o, d));
  }
};

}  // namespace sphray
