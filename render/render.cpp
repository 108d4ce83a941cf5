#include "render.h"

#include <algorithm>
#include <cmath>

namespace sphray {

Camera look_at(Vec3d eye, Vec3d target, double fov_deg, int width, int height) {
  Camera c{};
  const Vec3d f = (target - eye) * (1.0 / length(target - eye));
  Vec3d right{f.y, -f.x, 0.0};  // f x (0, 0, 1)
  if (length(right) < 1e-9) right = {1, 0, 0};  // looking straight up or down
  right = right * (1.0 / length(right));
  const Vec3d up{right.y * f.z - right.z * f.y, right.z * f.x - right.x * f.z, right.x * f.y - right.y * f.x};
  c.eye = to_f(eye);
  c.forward = to_f(f);
  c.right = to_f(right);
  c.up = to_f(up);
  c.tan_half_fov = float(std::tan(fov_deg * M_PI / 360.0));
  c.width = width;
  c.height = height;
  return c;
}

void camera_points(const Box& tank, const RenderSettings& r, Vec3d& eye, Vec3d& target) {
  eye = r.eye;
  target = r.target;
  if (length(eye - target) > 0) return;
  // Three-quarter view from the front (-y), a little to the right and above,
  // far enough that the whole tank fits the field of view.
  const Vec3d lo = tank.min, hi = tank.max, size = hi - lo;
  target = {lo.x + 0.5 * size.x, lo.y + 0.5 * size.y, lo.z + 0.3 * size.z};
  Vec3d dir{0.3, -1.0, 0.55};
  dir = dir * (1.0 / length(dir));
  const double tan_half = std::tan(r.fov * M_PI / 360.0), aspect = double(r.width) / double(r.height);
  eye = target + dir * (0.5 * length(size) / std::min(tan_half, tan_half * aspect) * 0.95);
}

Camera make_camera(const Box& tank, const RenderSettings& r) {
  Vec3d eye, target;
  camera_points(tank, r, eye, target);
  return look_at(eye, target, r.fov, r.width, r.height);
}

Environment make_environment(const Box& tank, const VolumeGeom& vol, const Camera& cam) {
  const Vec3d size = tank.max - tank.min;
  Environment e{};
  e.tank_lo = vol.to_voxels(to_f(tank.min));
  e.tank_hi = vol.to_voxels(to_f(tank.max));
  e.tile = float(std::max(size.x, size.y) / 16.0 / vol.voxel);
  e.sun = normalized(Vec3f{0.45f, 0.25f, 0.86f});
  // a wall is glass when the camera is on its outer side
  e.glass = (cam.eye.x < tank.min.x ? 1 : 0) | (cam.eye.x > tank.max.x ? 2 : 0) |
            (cam.eye.y < tank.min.y ? 4 : 0) | (cam.eye.y > tank.max.y ? 8 : 0);
  return e;
}

namespace {

// Planes normal to the view across the volume box's depth range, `slices` of them.
SlicePlanes slice_planes(const Camera& cam, const VolumeGeom& vol, int slices) {
  SlicePlanes p;
  p.eye = vol.to_voxels(cam.eye);
  p.forward = cam.forward;
  float lo = 1e30f, hi = -1e30f;
  for (int c = 0; c < 8; ++c) {
    const Vec3f corner{c & 1 ? float(vol.nx) : 0.0f, c & 2 ? float(vol.ny) : 0.0f, c & 4 ? float(vol.nz) : 0.0f};
    const float z = dot(corner - p.eye, p.forward);
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  lo = std::max(lo, 0.0f);
  p.z0 = lo;
  p.spacing = std::max(hi - lo, 1e-3f) / float(slices);
  return p;
}

}  // namespace

TraceSettings make_trace_settings(const RenderSettings& r, const FieldSetup& fs, const Camera& cam) {
  const double v = fs.geom.voxel;
  const bool slices = r.method == RenderMethod::Slices;
  const SlicePlanes planes = slices ? slice_planes(cam, fs.geom, r.slices) : SlicePlanes{};
  return TraceSettings{fs.shape.iso,
                       slices ? planes.spacing : r.step,
                       r.interfaces,
                       r.ior,
                       Rgb{float(r.absorption.x * v), float(r.absorption.y * v), float(r.absorption.z * v)},
                       slices ? 0 : r.secant_steps,
                       r.reflections,
                       r.budget,
                       float(r.min_weight),
                       Rgb{float(r.tint.x), float(r.tint.y), float(r.tint.z)},
                       planes};
}

std::unique_ptr<Renderer> make_renderer(Backend b) {
  return b == Backend::Cuda ? make_cuda_renderer() : make_cpu_renderer();
}

#if !defined(SPHRAY_HAVE_CUDA)
std::unique_ptr<Renderer> make_cuda_renderer() { throw_no_cuda(); }
#endif

}  // namespace sphray
