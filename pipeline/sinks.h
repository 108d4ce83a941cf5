// The outputs of `sphray run` and `sphray render` as sinks of the run loop
// (pipeline.h): PNG frames, the HDF5 export, the metrics CSV. Each says what
// it needs at a frame; the pipeline derives the stages from that.
#pragma once

#include <fstream>
#include <memory>
#include <set>
#include <string>

#include "dist/rank_export.h"
#include "io/frames_h5.h"
#include "pipeline.h"
#include "render/frame_sink.h"

namespace sphray {

// PNG frames into a directory, every `every`-th output frame
// (render.frames_every). Its renderer is made by open(), once the field's
// volume is known; the directory is checked then, before the run. It needs
// the field where the scene's render.method draws one.
class PngSink final : public OutputSink {
 public:
  PngSink(std::string dir, const RenderSettings& rs, std::string flag = "--frames-dir")
      : dir_(std::move(dir)), flag_(std::move(flag)), every_(rs.frames_every), field_(method_needs_field(rs.method)) {}
  void open(const Scene& scene, Backend b, const FieldSetup& fs);
  FrameRenderer& frames() { return *frames_; }
  FrameNeeds needs(int frame) const override { return {field_ && frame % every_ == 0, false}; }
  FrameNeeds needs_ever() const override { return {field_, false}; }
  void write(const Solver& s, const FieldBuilder* field, int frame) override;
  // The obstacles' skins as the solver's waves displace them now, for the
  // next render (write does it itself).
  void draw_skins(const Solver& s);

 private:
  std::string dir_, flag_;
  int every_;
  bool field_;
  std::unique_ptr<FrameRenderer> frames_;
  std::vector<MeshInput> meshes_;  // the scene's obstacles
  bool skins_drawn_ = false;       // the skins' surfaces replace them (drawn_obstacles)
};

// HDF5 frames (--export), every `every`-th output frame, with the datasets
// in `fields` (io/export.h). Its file is created by open() (rank 0 writes
// it, from a background thread) or open_ranks() (every rank of a run over
// several writes its rows, dist/rank_export.h), before the run.
class ExportSink final : public OutputSink {
 public:
  ExportSink(int every, std::set<std::string> fields, const SphParams& prm)
      : every_(every), fields_(std::move(fields)), prm_(prm) {}
  void open(const std::string& path, const FileHeader& header, int gzip) {
    writer_ = std::make_unique<FrameWriter>(path, header, gzip);
  }
  void open_ranks(const std::string& path, const FileHeader& header, Comm& comm) {
    ranks_ = std::make_unique<RankFrameWriter>(path, header, comm);
  }
  bool by_ranks() const { return ranks_ != nullptr; }
  // Waits for the frames still queued (collective for open_ranks()); throws a write error.
  void finish() { ranks_ ? ranks_->finish() : writer_->finish(); }
  size_t frames_written() const { return ranks_ ? ranks_->frames_written() : writer_->frames_written(); }
  // The run's time spent on the export: waiting on the writer thread, or writing (open_ranks()).
  double seconds_in_run() const { return ranks_ ? ranks_->seconds_writing() : writer_->seconds_waited(); }
  FrameNeeds needs(int frame) const override;
  FrameNeeds needs_ever() const override { return {fields_.count("field") > 0, fields_.count("presence") > 0}; }
  void write(const Solver& s, const FieldBuilder* field, int frame) override;

 private:
  int every_;
  std::set<std::string> fields_;
  SphParams prm_;
  std::unique_ptr<FrameWriter> writer_;
  std::unique_ptr<RankFrameWriter> ranks_;
};

// The metrics CSV (--metrics-csv): time, steps, particles, surge front,
// kinetic energy, the largest speed and the water height at each of the
// scene's gauges per output frame, flushed per row.
// `flag` names the option in messages.
class MetricsSink final : public OutputSink {
 public:
  MetricsSink(const std::string& path, const Scene& scene, const SphParams& prm, std::string flag = "--metrics-csv");
  FrameNeeds needs(int) const override { return {}; }
  FrameNeeds needs_ever() const override { return {}; }
  void write(const Solver& s, const FieldBuilder* field, int frame) override;
  // Closes the file; a write error is an OutputError.
  void finish();

 private:
  std::ofstream csv_;
  std::string path_, flag_;
  double back_wall_x_, spacing_, mass_;
  std::vector<Gauge> gauges_;
  double floor_, top_;
  SmoothingKernel<double> kernel_;
  double volume_;
};

// "FLAG: cannot write 'PATH': reason", the reason from errno when a write set it.
std::string write_failure(const std::string& flag, const std::string& path);
// Opens an output file before the work that fills it, so that a bad path
// fails at once (std::runtime_error: bad input, exit 2).
std::ofstream open_output(const std::string& flag, const std::string& path);

}  // namespace sphray
