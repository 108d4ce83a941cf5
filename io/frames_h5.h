// HDF5 frame files (docs/formats.md): a writer that takes frames from the
// simulation and writes them from a background thread (double buffering: the
// run waits only when a frame is still queued behind the one being written),
// flushing after each so a killed run leaves every earlier frame readable,
// with an XDMF sidecar for ParaView; and a reader for `sphray inspect`, the
// tests and later re-rendering.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/background.h"
#include "xdmf.h"

#include "field/volume.h"

namespace sphray {

constexpr const char* kFramesFormat = "sphray-frames";
constexpr int kFramesFormatVersion = 1;

// A file that cannot be written, read, or is not a sphray frames file.
struct FrameFileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char* sphray_version();

// Names accepted by --export-fields (position is always written).
const std::vector<std::string>& exportable_fields();

// The XDMF sidecar of an export: its path with the extension replaced by
// .xmf (out.h5 -> out.xmf).
std::string xdmf_path(const std::string& h5);

struct Frame {
  double time = 0, dt = 0;
  uint64_t step = 0;
  std::vector<uint32_t> id;         // initial particle index, ascending
  std::vector<float> position;      // N x 3
  std::vector<float> velocity;      // N x 3 or empty
  std::vector<float> density;       // N or empty
  std::vector<float> pressure;      // N or empty
  std::vector<float> presence;      // N x 6 (+x,-x,+y,-y,+z,-z) or empty
  std::vector<float> field;         // nz x ny x nx or empty
  int field_dims[3] = {0, 0, 0};    // nx, ny, nz
  float field_origin[3] = {0, 0, 0}, field_voxel = 0, field_iso = 0;
  // Obstacle skins' heights (sph/skin.h): per skinned obstacle its index in
  // the scene's "obstacles" and 6 x n x n heights [m] (face, row, column).
  struct Skin {
    uint32_t obstacle = 0;
    int n = 0;
    std::vector<float> height;
  };
  std::vector<Skin> skins;
  size_t count() const { return id.size(); }
};

struct FileHeader {
  std::string scene_json, version, backend;
  std::vector<float> boundary;  // B x 3
};

class FrameWriter {
 public:
  // Creates (truncates) `path` and writes the header at once, so a bad path
  // fails before the run. gzip: 0 (off) .. 9.
  FrameWriter(const std::string& path, const FileHeader& header, int gzip);
  ~FrameWriter();  // finishes writing; errors are reported by finish()
  FrameWriter(const FrameWriter&) = delete;
  FrameWriter& operator=(const FrameWriter&) = delete;

  // Queues a frame; blocks only while another frame is still queued. Throws
  // FrameFileError if an earlier write failed.
  void submit(Frame&& f);
  // Same, with the frame made on the writer thread (conversions off the run's
  // thread); the frame is released once written (its buffers may be reused).
  void submit(std::function<std::shared_ptr<const Frame>()> make);
  // Waits for the queue to drain and closes the file; throws on a write error.
  void finish();
  size_t frames_written() const { return queue_ ? queue_->done() : 0; }
  double seconds_waited() const { return queue_ ? queue_->seconds_waited() : 0.0; }  // time submit() blocked the run
  size_t sidecar_writes() const { return xdmf_writes_; }  // times the XDMF sidecar was written (after finish())

 private:
  void write(const Frame& f);
  void write_xdmf();

  std::string path_;
  int gzip_;
  int64_t file_ = -1;
  size_t boundary_ = 0;  // wall particles in /boundary/position
  std::vector<XdmfFrame> xdmf_;  // what the sidecar says of each written frame (writer thread)
  // The sidecar on disk: frames it describes, its size, when it was written.
  size_t xdmf_written_ = 0, xdmf_writes_ = 0;
  double xdmf_bytes_ = 0;
  std::chrono::steady_clock::time_point xdmf_time_{};
  std::unique_ptr<BackgroundQueue> queue_;       // last: started once the header is written
};

struct FrameInfo {
  std::string name;  // group name under /frames
  double time = 0, dt = 0;
  uint64_t step = 0;
  size_t particles = 0;
  std::vector<std::string> datasets;
};

class FrameReader {
 public:
  explicit FrameReader(const std::string& path);  // throws FrameFileError naming what is wrong
  ~FrameReader();
  FrameReader(const FrameReader&) = delete;
  FrameReader& operator=(const FrameReader&) = delete;
  const FileHeader& header() const { return header_; }
  int format_version() const { return version_; }
  const std::vector<FrameInfo>& frames() const { return frames_; }
  Frame read(size_t k) const;  // every dataset the frame holds

 private:
  std::string path_;
  int64_t file_ = -1;
  int version_ = 0;
  FileHeader header_;
  std::vector<FrameInfo> frames_;
};

}  // namespace sphray
