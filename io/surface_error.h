// The iso-surface of a density field against analytic surfaces: how far from
// the true liquid surface the renderer's surface lies and how tilted its
// normal is (docs/field.md, "Surface error"). The field is sampled as the
// raycaster samples it (trilinear between voxel centres), the surface found
// along rays as a marching ray finds it (fine steps, then bisection), and the
// normal is the raycaster's (render/raycast.h, field_normal).
#pragma once

#include <cstddef>
#include <vector>

#include "core/vec.h"
#include "field/volume.h"

namespace sphray {

struct SurfaceError {
  size_t rays = 0;
  size_t missed = 0;          // rays that met no surface (not in the statistics)
  double rms_distance = 0;    // [m] surface found - analytic surface, along the ray's outward direction
  double mean_distance = 0;   // [m] signed: > 0 outside the analytic surface
  double max_distance = 0;    // [m] largest |distance|
  double rms_angle_deg = 0;   // normal against the analytic normal
  double max_angle_deg = 0;
};

// The horizontal plane z = height [m] seen from above: one vertical ray per
// `pitch` [m] over [lo.x, hi.x] x [lo.y, hi.y], from hi.z down to lo.z.
SurfaceError plane_surface_error(const std::vector<float>& field, const VolumeGeom& vol, float iso, Vec3d lo,
                                 Vec3d hi, double height, double pitch);

// The sphere (centre, radius) [m] seen from outside: `rays` rays aimed at the
// centre from directions spread evenly over the sphere (a Fibonacci lattice),
// each starting `margin` [m] outside the sphere.
SurfaceError sphere_surface_error(const std::vector<float>& field, const VolumeGeom& vol, float iso, Vec3d centre,
                                  double radius, int rays, double margin);

// Holes in a horizontal sheet of liquid: one vertical ray per `pitch` [m] over
// [lo.x, hi.x] x [lo.y, hi.y] from hi.z down to lo.z; a ray that meets no
// inside point passes through a hole.
struct SheetHoles {
  size_t rays = 0, holes = 0;
  double share() const { return rays ? double(holes) / double(rays) : 0.0; }
};
SheetHoles sheet_holes(const std::vector<float>& field, const VolumeGeom& vol, float iso, Vec3d lo, Vec3d hi,
                       double pitch);

}  // namespace sphray
