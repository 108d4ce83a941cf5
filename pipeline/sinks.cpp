#include "sinks.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <iomanip>
#include <stdexcept>

#include "io/export.h"
#include "io/metrics.h"

namespace sphray {

std::string write_failure(const std::string& flag, const std::string& path) {
  return flag + ": cannot write '" + path + "'" + (errno ? std::string(": ") + std::strerror(errno) : "");
}

std::ofstream open_output(const std::string& flag, const std::string& path) {
  errno = 0;
  std::ofstream f(path);
  if (!f) throw std::runtime_error(write_failure(flag, path));
  return f;
}

void PngSink::open(const Scene& scene, Backend b, const FieldSetup& fs) {
  frames_ = std::make_unique<FrameRenderer>(scene.render, scene.tank, scene.sph.spacing, b, fs, dir_, flag_);
  meshes_ = obstacle_meshes(scene);
  frames_->set_obstacles(meshes_);
}

void PngSink::draw_skins(const Solver& s) {
  if (!s.skins()) return;
  if (!skins_drawn_) frames_->set_obstacles(drawn_obstacles(meshes_, s));
  skins_drawn_ = true;
  show_skins(s, frames_->renderer());
}

void PngSink::write(const Solver& s, const FieldBuilder* field, int frame) {
  if (frame % every_ != 0) return;
  draw_skins(s);
  frames_->write_frame(s.view(), field, frame, s.time());
}

FrameNeeds ExportSink::needs(int frame) const { return frame % every_ == 0 ? needs_ever() : FrameNeeds{}; }

void ExportSink::write(const Solver& s, const FieldBuilder* field, int frame) {
  if (frame % every_ != 0) return;
  if (ranks_) ranks_->write(s, prm_, fields_);
  else writer_->submit(capture_frame(s, prm_, fields_, field));
}

// Opened before the run, so that an unwritable path fails in a second, not
// after the simulation (bad input).
MetricsSink::MetricsSink(const std::string& path, const Scene& scene, const SphParams& prm, std::string flag)
    : path_(path), flag_(std::move(flag)), back_wall_x_(scene.tank.min.x), spacing_(scene.sph.spacing),
      mass_(prm.particle_mass), gauges_(scene.gauges), floor_(scene.tank.min.z), top_(scene.tank.max.z),
      kernel_(SmoothingKernel<double>::make(prm.kernel.type, prm.kernel.h)),
      volume_(double(prm.particle_mass) / double(prm.rest_density)) {
  csv_ = open_output(flag_, path);
  csv_ << "time_s,steps,fluid_particles,front_m,kinetic_energy_J,max_speed_m_s";
  for (const Gauge& g : gauges_) csv_ << "," << g.name << "_m";
  csv_ << "\n" << std::setprecision(9);
}

// Flushed per row: a run followed live (tail -f) or killed leaves whole rows,
// and a write error (a full disk) stops the run here rather than end with a
// cut-off CSV and exit 0.
// Without gauges the row's reductions run where the particles are
// (Solver::flow_sums: no download of every particle per row).
void MetricsSink::write(const Solver& s, const FieldBuilder*, int) {
  const FlowSums f = s.flow_sums();
  errno = 0;
  csv_ << s.time() << "," << s.steps() << "," << s.num_fluid() << "," << surge_front(f, back_wall_x_, spacing_) << ","
       << kinetic_energy(f, mass_) << "," << s.last_limits().max_speed;
  if (!gauges_.empty()) {
    const HostParticles p = s.download();
    for (const Gauge& g : gauges_) csv_ << "," << water_height(p, g.x, g.y, kernel_, volume_, floor_, top_, spacing_);
  }
  csv_ << "\n" << std::flush;
  if (!csv_) throw OutputError(write_failure(flag_, path_));
}

void MetricsSink::finish() {
  errno = 0;
  csv_.close();
  if (!csv_) throw OutputError(write_failure(flag_, path_));
}

}  // namespace sphray
