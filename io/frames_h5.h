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
#include <utility>
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
// The directory a file of `path` lies in ("." for a bare name).
std::string directory_of(const std::string& path);

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

// The XDMF sidecar of an export as its frames are written: rewritten whole
// (to a .tmp renamed into place, so it is never seen half written), after
// every frame up to 16, then once the frames not yet in it reach 1/16 of
// those in it or a second has passed, and at finish() (docs/formats.md).
class XdmfSidecar {
 public:
  XdmfSidecar(std::string h5_path, size_t boundary) : h5_(std::move(h5_path)), boundary_(boundary) {}
  void add(const XdmfFrame& f);  // throws FrameFileError when the sidecar cannot be written
  void finish();                 // writes the frames not yet in it
  size_t frames() const { return frames_.size(); }
  size_t writes() const { return writes_; }
  double bytes() const { return bytes_; }  // of the sidecar on disk

 private:
  void write();
  std::string h5_;
  size_t boundary_;
  std::vector<XdmfFrame> frames_;
  size_t written_ = 0, writes_ = 0;  // frames it describes on disk; times written
  double bytes_ = 0;
  std::chrono::steady_clock::time_point time_{};
};

// What a frame's sidecar entry says of it.
XdmfFrame xdmf_frame_of(const Frame& f);

// Throws FrameFileError when the file system of `path` has too little room
// for frame `name` of `values` 4-byte values in `datasets` datasets
// (checked before a frame is written: a write that fails half way (disk
// full) can leave HDF5's metadata inconsistent); `sidecar_bytes` for the
// sidecar's rewrite, `written` for the message.
void check_frame_space(const std::string& path, const std::string& name, const std::vector<size_t>& values,
                       double sidecar_bytes, size_t written);

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
  size_t sidecar_writes() const { return xdmf_ ? xdmf_->writes() : 0; }  // times the XDMF sidecar was written (after finish())

 private:
  void write(const Frame& f);

  std::string path_;
  int gzip_;
  int64_t file_ = -1;
  std::unique_ptr<XdmfSidecar> xdmf_;        // written on the writer thread
  std::unique_ptr<BackgroundQueue> queue_;   // last: started once the header is written
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
