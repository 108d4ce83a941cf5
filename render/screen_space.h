// Screen-space two-sided refraction (Imai, Kanamori, Fukui & Mitani,
// "Real-Time Screen-Space Liquid Rendering with Two-Sided Refractions";
// docs/rendering.md, docs/references.md), once for both backends. It draws the particles, not the
// density field:
//  1. depth: every particle is a sphere of radius r; per pixel the nearest
//     entry (front) and the farthest exit (back) of the camera ray through any
//     sphere, as view depths (the two layers of their dual depth peeling, here
//     by an atomic min and max);
//  2. filter: both maps smoothed together by `iterations` passes of a
//     bilateral filter of half-width w pixels (their eq. 1-2: sigma_1 =
//     w / (2 sqrt 2), sigma_2 = 2 sqrt 2 r); empty pixels stay empty and do
//     not take part;
//  3. shade: normals from the smoothed depths (the smaller of the one-sided
//     differences, van der Laan et al. 2009); Schlick's Fresnel at the front;
//     the refracted ray meets the back layer by the secant method on the
//     depth difference (their eq. 4-6; where the ray leaves the drawn liquid
//     the step is halved); refraction out at the back (total internal
//     reflection: reflected); Beer-Lambert absorption over the path between
//     the two layers (cut where it meets the tank's floor or walls), the
//     absorbed share taking the liquid's tint as in the raycaster. Colour = F C_front + (1 - F) C_through (their eq. 7).
// All in world units (metres); the environment is looked up in its voxel frame.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/atomics.h"
#include "core/hd.h"
#include "core/vec.h"
#include "environment.h"
#include "field/volume.h"
#include "optics.h"
#include "raycast.h"

namespace sphray {

// Depth maps hold non-negative view depths as their float bit patterns
// (ordered like the floats, so atomic min / max on the bits work).
constexpr uint32_t kNoFront = 0x7f800000u;  // +infinity: no liquid at this pixel
constexpr uint32_t kNoBack = 0u;

// The camera's view frame and its projection (the inverse of Camera::direction).
struct ViewFrame {
  Camera cam;

  SPHRAY_HD SPHRAY_FORCEINLINE float aspect() const { return float(cam.width) / float(cam.height); }
  // View coordinates of a world point: x right, y up, z the depth along forward.
  SPHRAY_HD SPHRAY_FORCEINLINE Vec3f view(Vec3f p) const {
    const Vec3f v = p - cam.eye;
    return {dot(v, cam.right), dot(v, cam.up), dot(v, cam.forward)};
  }
  // Continuous pixel coordinates (pixel i spans [i, i + 1), row 0 at the top)
  // of tangents sx = x / z, sy = y / z.
  SPHRAY_HD SPHRAY_FORCEINLINE float px(float sx) const {
    return (sx / (cam.tan_half_fov * aspect()) + 1.0f) * 0.5f * float(cam.width);
  }
  SPHRAY_HD SPHRAY_FORCEINLINE float py(float sy) const {
    return (1.0f - sy / cam.tan_half_fov) * 0.5f * float(cam.height);
  }
  // The world point at view depth z on the ray through pixel (x, y)'s centre.
  SPHRAY_HD SPHRAY_FORCEINLINE Vec3f at_depth(int x, int y, float z) const {
    const Vec3f d = cam.direction(float(x) + 0.5f, float(y) + 0.5f);
    return cam.eye + d * (z / dot(d, cam.forward));
  }
};

struct ClearDepth {
  uint32_t* front;
  uint32_t* back;
  SPHRAY_HD void operator()(uint32_t i) const {
    front[i] = kNoFront;
    back[i] = kNoBack;
  }
};

// One thread per particle: the pixels whose centre ray meets its sphere.
struct SplatSpheres {
  ViewFrame view;
  const Float4* pos;
  float r;  // sphere radius [m]
  uint32_t* front;
  uint32_t* back;

  SPHRAY_HD void operator()(uint32_t i) const {
    const Camera& cam = view.cam;
    const Vec3f c = xyz(load(pos + i));
    const Vec3f v = c - cam.eye;
    const Vec3f w = view.view(c);
    if (w.z - r <= 1e-6f) return;  // reaches the eye's plane: not drawn
    // The sphere lies in the box w +- r; so does its projection within the
    // box's: the extreme tangents over the box's near and far depth.
    const float zn = w.z - r, zf = w.z + r;
    const float sx0 = (w.x - r) / (w.x - r < 0.0f ? zn : zf), sx1 = (w.x + r) / (w.x + r > 0.0f ? zn : zf);
    const float sy0 = (w.y - r) / (w.y - r < 0.0f ? zn : zf), sy1 = (w.y + r) / (w.y + r > 0.0f ? zn : zf);
    int x0 = int(std::ceil(view.px(sx0) - 0.5f)), x1 = int(std::floor(view.px(sx1) - 0.5f));
    int y0 = int(std::ceil(view.py(sy1) - 0.5f)), y1 = int(std::floor(view.py(sy0) - 0.5f));
    x0 = x0 < 0 ? 0 : x0;
    y0 = y0 < 0 ? 0 : y0;
    x1 = x1 > cam.width - 1 ? cam.width - 1 : x1;
    y1 = y1 > cam.height - 1 ? cam.height - 1 : y1;
    const float r2 = r * r;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const Vec3f d = cam.direction(float(x) + 0.5f, float(y) + 0.5f);
        const float b = dot(d, v);
        const Vec3f off = v - d * b;  // the centre's offset from the ray: well conditioned far away
        const float disc = r2 - dot(off, off);
        if (disc < 0.0f) continue;
        const float s = std::sqrt(disc), cz = dot(d, cam.forward);
        const size_t k = size_t(y) * size_t(cam.width) + size_t(x);
        const uint32_t zf_bits = float_to_bits((b - s) * cz), zb_bits = float_to_bits((b + s) * cz);
        atomic_min(front + k, zf_bits);
        atomic_max(back + k, zb_bits);
      }
  }
};

// One pass of the bilateral filter over both maps (in -> out).
struct BilateralDepth {
  static constexpr int kMaxWidth = 16;
  const uint32_t* in_front;
  const uint32_t* in_back;
  uint32_t* out_front;
  uint32_t* out_back;
  int width, height, w;
  float spatial[kMaxWidth + 1];  // exp(-m^2 / (2 sigma_1^2)), m = 0 .. w
  float inv_2s2;                 // 1 / (2 sigma_2^2) [1/m^2]

  // The paper's weights for half-width w pixels and spheres of radius r [m]
  // (the maps still to be set).
  static BilateralDepth weights(int width, int height, int w, float r) {
    BilateralDepth f{};
    f.width = width;
    f.height = height;
    f.w = w;
    const float s1 = float(w) / (2.0f * std::sqrt(2.0f)), s2 = 2.0f * std::sqrt(2.0f) * r;
    for (int m = 0; m <= kMaxWidth; ++m) f.spatial[m] = std::exp(-float(m * m) / (2.0f * s1 * s1));
    f.inv_2s2 = 1.0f / (2.0f * s2 * s2);
    return f;
  }

  SPHRAY_HD void operator()(uint32_t k) const {
    const int x = int(k % uint32_t(width)), y = int(k / uint32_t(width));
    if (in_front[k] == kNoFront) {
      out_front[k] = kNoFront;
      out_back[k] = kNoBack;
      return;
    }
    const float zf = bits_to_float(in_front[k]), zb = bits_to_float(in_back[k]);
    float sf = 0, wf = 0, sb = 0, wb = 0;
    for (int n = -w; n <= w; ++n) {
      const int j = y + n;
      if (j < 0 || j >= height) continue;
      for (int m = -w; m <= w; ++m) {
        const int i = x + m;
        if (i < 0 || i >= width) continue;
        const size_t q = size_t(j) * size_t(width) + size_t(i);
        if (in_front[q] == kNoFront) continue;
        const float g = spatial[m < 0 ? -m : m] * spatial[n < 0 ? -n : n];
        const float f = bits_to_float(in_front[q]), b = bits_to_float(in_back[q]);
        const float gf = g * std::exp(-(f - zf) * (f - zf) * inv_2s2);
        const float gb = g * std::exp(-(b - zb) * (b - zb) * inv_2s2);
        sf += gf * f;
        wf += gf;
        sb += gb * b;
        wb += gb;
      }
    }
    out_front[k] = float_to_bits(sf / wf);  // the pixel itself has weight 1
    out_back[k] = float_to_bits(sb / wb);
  }
};

struct ShadeTwoSided {
  ViewFrame view;
  Environment env;
  VolumeGeom vol;  // the environment's voxel frame
  const uint32_t* front;
  const uint32_t* back;
  float r;                // sphere radius [m]: the secant search's tolerance is 1% of it
  float ior;
  Rgb absorption;         // per metre
  Rgb tint;
  int secant_steps;
  uint32_t* rgba;

  SPHRAY_HD SPHRAY_FORCEINLINE bool filled(int x, int y) const {
    return x >= 0 && y >= 0 && x < view.cam.width && y < view.cam.height &&
           front[size_t(y) * size_t(view.cam.width) + size_t(x)] != kNoFront;
  }
  SPHRAY_HD SPHRAY_FORCEINLINE float depth(const uint32_t* map, int x, int y) const {
    return bits_to_float(map[size_t(y) * size_t(view.cam.width) + size_t(x)]);
  }
  // Unit normal of the layer `map` at pixel (x, y) (filled), from the view
  // positions of its neighbours: on each axis the one-sided difference with
  // the smaller depth step (edges do not bleed in). Its sign is the caller's.
  SPHRAY_HD Vec3f normal(const uint32_t* map, int x, int y) const {
    const float z = depth(map, x, y);
    const Vec3f p = view.at_depth(x, y, z);
    auto side = [&](int dx, int dy) {
      const bool hi = filled(x + dx, y + dy), lo = filled(x - dx, y - dy);
      if (!hi && !lo) return Vec3f{0, 0, 0};
      const float zh = hi ? depth(map, x + dx, y + dy) : 0.0f, zl = lo ? depth(map, x - dx, y - dy) : 0.0f;
      const bool use_hi = hi && (!lo || std::fabs(zh - z) <= std::fabs(z - zl));
      return use_hi ? view.at_depth(x + dx, y + dy, zh) - p : p - view.at_depth(x - dx, y - dy, zl);
    };
    const Vec3f ex = side(1, 0), ey = side(0, 1);
    const Vec3f n = cross(ex, ey);
    const float l2 = dot(n, n);
    return l2 > 0.0f ? n * (1.0f / std::sqrt(l2)) : Vec3f{0, 0, 0};
  }
  // The environment seen from p along d. The spheres of the particles next
  // to a wall or the floor reach past it by up to a radius: p is taken back
  // inside the tank (the open top stays open).
  SPHRAY_HD SPHRAY_FORCEINLINE Rgb look(Vec3f p, Vec3f d) const {
    const float e = 0.01f;  // voxels: strictly inside, so the floor or wall is met ahead
    const Vec3f lo = env.tank_lo + Vec3f{e, e, e}, hi = env.tank_hi - Vec3f{e, e, e};
    Vec3f u = vol.to_voxels(p);
    u.x = u.x < lo.x ? lo.x : (u.x > hi.x ? hi.x : u.x);
    u.y = u.y < lo.y ? lo.y : (u.y > hi.y ? hi.y : u.y);
    u.z = u.z < lo.z ? lo.z : u.z;
    return env(u, d);
  }

  // Depth of the ray point q minus the back layer where q projects; false
  // where q projects onto no liquid (or behind the eye).
  SPHRAY_HD bool behind_back(Vec3f q, float& dz, int& x, int& y) const {
    const Vec3f w = view.view(q);
    if (!(w.z > 0.0f)) return false;
    x = int(std::floor(view.px(w.x / w.z)));
    y = int(std::floor(view.py(w.y / w.z)));
    if (!filled(x, y)) return false;
    dz = w.z - depth(back, x, y);
    return true;
  }

  // The secant search (eq. 4-6) for where the ray pf + t t_dir (refracted
  // at the front, depth zf, of a pixel whose back layer is at depth zb)
  // meets the back layer: t, and the pixel (bx, by) it projects to. Where the
  // ray projects onto no liquid the step is halved (the paper's rule); 0
  // when no point of it does.
  SPHRAY_HD float back_distance(Vec3f pf, Vec3f t_dir, float zf, float zb, int& bx, int& by) const {
    float ts = 0.0f, ds = zf - zb;
    const float cz = dot(t_dir, view.cam.forward);
    float te = (zb - zf) / (cz > 0.2f ? cz : 0.2f);
    if (!(te > 0.0f)) te = r;
    float de = 0.0f;
    bool ok = behind_back(pf + t_dir * te, de, bx, by);
    for (int h = 0; !ok && h < 8; ++h) ok = behind_back(pf + t_dir * (te *= 0.5f), de, bx, by);
    if (!ok) return 0.0f;
    float t = te;
    for (int s = 0; s < secant_steps && de != ds && std::fabs(de) > 0.01f * r; ++s) {
      float tn = ts - (te - ts) / (de - ds) * ds;
      if (!(tn > 0.0f)) tn = 0.5f * (ts + te);
      float dn;
      int nx, ny;
      bool hit = behind_back(pf + t_dir * tn, dn, nx, ny);
      for (int h = 0; !hit && h < 8; ++h) hit = behind_back(pf + t_dir * (tn *= 0.5f), dn, nx, ny);
      if (!hit) break;
      t = tn;
      bx = nx;
      by = ny;
      // within a bracket, replace its end on dn's side (regula falsi);
      // without one, the older point (secant)
      if ((ds < 0.0f) != (de < 0.0f)) {
        if ((dn < 0.0f) == (ds < 0.0f)) { ts = tn; ds = dn; }
        else { te = tn; de = dn; }
      } else {
        ts = te; ds = de; te = tn; de = dn;
      }
      if (ts > te) {
        const float a = ts, b = ds;
        ts = te; ds = de; te = a; de = b;
      }
      if (std::fabs(dn) <= 0.01f * r) break;
    }
    return t;
  }

  SPHRAY_HD void operator()(uint32_t idx) const {
    int x, y;
    const Camera& cam = view.cam;
    if (!PixelTiles{cam.width, cam.height}.pixel(idx, x, y)) return;
    const Vec3f d = cam.direction(float(x) + 0.5f, float(y) + 0.5f);
    const size_t k = size_t(y) * size_t(cam.width) + size_t(x);
    if (!filled(x, y)) {
      rgba[k] = encode_rgba8(env(vol.to_voxels(cam.eye), d));
      return;
    }
    const float zf = depth(front, x, y);
    const Vec3f pf = view.at_depth(x, y, zf);
    Vec3f nf = normal(front, x, y);
    if (dot(nf, d) > 0.0f) nf = -nf;  // toward the eye
    if (nf.x == 0.0f && nf.y == 0.0f && nf.z == 0.0f) nf = -d;
    const float cos_i = -dot(nf, d);
    const float F = schlick(1.0f, ior, cos_i > 0.0f ? cos_i : 0.0f);
    const Rgb c_front = look(pf, reflect(d, nf));
    Vec3f t_dir;
    float cos_t;
    if (!refract(d, nf, 1.0f / ior, t_dir, cos_t)) t_dir = d;  // (from air it cannot fail)
    t_dir = normalized(t_dir);

    int bx = x, by = y;
    float t = back_distance(pf, t_dir, zf, depth(back, x, y), bx, by);
    // The spheres next to the floor or a wall reach past it: the liquid ends
    // there, and on the floor or an opaque wall the ray ends on its tiles.
    const Vec3f uf = vol.to_voxels(pf);
    int wall = -1;
    if (env.in_tank(uf)) {
      float te;
      const int face = env.exit_face(uf, t_dir, te);
      if (face != 5 && te * vol.voxel <= t) {
        t = te * vol.voxel;
        if (env.opaque(face)) wall = face;
      }
    }
    const Vec3f pb = pf + t_dir * t;
    Rgb c_back;
    if (wall >= 0) {
      c_back = env.surface(wall, vol.to_voxels(pb), t_dir);
    } else {
      Vec3f nb = normal(back, bx, by);
      if (nb.x == 0.0f && nb.y == 0.0f && nb.z == 0.0f) nb = t_dir;
      if (dot(nb, t_dir) < 0.0f) nb = -nb;  // outward, along the ray
      Vec3f out;
      if (!refract(t_dir, -nb, ior, out, cos_t)) out = reflect(t_dir, -nb);
      c_back = look(pb, normalized(out));
    }
    const Rgb T{std::exp(-absorption.r * t), std::exp(-absorption.g * t), std::exp(-absorption.b * t)};
    const Rgb through = c_back * T + tint * Rgb{1.0f - T.r, 1.0f - T.g, 1.0f - T.b};
    rgba[k] = encode_rgba8(c_front * F + through * (1.0f - F));
  }
};

}  // namespace sphray
