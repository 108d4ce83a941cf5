#include "frames_h5.h"

#include <fcntl.h>
#include <hdf5.h>
#include <sys/file.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include "h5.h"

namespace sphray {

const char* sphray_version() { return SPHRAY_VERSION; }

std::string xdmf_path(const std::string& h5) {
  const size_t dot = h5.rfind('.'), slash = h5.rfind('/');
  const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash);
  return (has_ext ? h5.substr(0, dot) : h5) + ".xmf";
}

std::string directory_of(const std::string& path) {
  const size_t slash = path.rfind('/');
  return slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
}

const std::vector<std::string>& exportable_fields() {
  static const std::vector<std::string> f = {"velocity", "density", "pressure", "presence", "field"};
  return f;
}

using h5::check;
using h5::fail;
using h5::Handle;

namespace {

void attr_string(hid_t loc, const char* name, const std::string& value, const std::string& path) {
  Handle type{check(H5Tcopy(H5T_C_S1), path, "string type"), H5Tclose};
  H5Tset_size(type.id, H5T_VARIABLE);
  H5Tset_cset(type.id, H5T_CSET_UTF8);
  Handle space{check(H5Screate(H5S_SCALAR), path, "dataspace"), H5Sclose};
  Handle a{check(H5Acreate2(loc, name, type.id, space.id, H5P_DEFAULT, H5P_DEFAULT), path,
                 std::string("creating attribute ") + name),
           H5Aclose};
  const char* p = value.c_str();
  if (H5Awrite(a.id, type.id, &p) < 0) fail(path, std::string("writing attribute ") + name);
}

template <class T>
void attr_array(hid_t loc, const char* name, hid_t mem_type, hid_t file_type, const T* v, hsize_t n,
                const std::string& path) {
  Handle space{check(n == 1 ? H5Screate(H5S_SCALAR) : H5Screate_simple(1, &n, nullptr), path, "dataspace"), H5Sclose};
  Handle a{check(H5Acreate2(loc, name, file_type, space.id, H5P_DEFAULT, H5P_DEFAULT), path,
                 std::string("creating attribute ") + name),
           H5Aclose};
  if (H5Awrite(a.id, mem_type, v) < 0) fail(path, std::string("writing attribute ") + name);
}

void attr_double(hid_t loc, const char* name, double v, const std::string& path) {
  attr_array(loc, name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, &v, 1, path);
}

// A dataset of rows x cols (cols 1: one dimension; `shape` overrides for 3D),
// chunked (with gzip when asked) unless empty.
void dataset(hid_t loc, const char* name, hid_t mem_type, hid_t file_type, const void* data,
             const std::vector<hsize_t>& dims, int gzip, const std::string& path) {
  Handle space{check(H5Screate_simple(int(dims.size()), dims.data(), nullptr), path, "dataspace"), H5Sclose};
  Handle dcpl{check(H5Pcreate(H5P_DATASET_CREATE), path, "property list"), H5Pclose};
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  hsize_t chunk_rows = 0;  // rows (or z slices) a chunk
  if (total > 0) {
    std::vector<hsize_t> chunk = dims;
    // About 1 MiB chunks: rows of particles, or z slices of the volume.
    hsize_t row = 4;
    for (size_t k = 1; k < dims.size(); ++k) row *= dims[k];
    chunk[0] = std::max<hsize_t>(1, std::min<hsize_t>(dims[0], (hsize_t(1) << 20) / row));
    H5Pset_chunk(dcpl.id, int(chunk.size()), chunk.data());
    chunk_rows = chunk[0];
    if (gzip > 0) {
      H5Pset_shuffle(dcpl.id);
      H5Pset_deflate(dcpl.id, unsigned(gzip));
    }
  }
  Handle d{check(H5Dcreate2(loc, name, file_type, space.id, H5P_DEFAULT, dcpl.id, H5P_DEFAULT), path,
                 std::string("creating dataset ") + name),
           H5Dclose};
  if (total == 0) return;
  // Uncompressed, and the memory layout already the file's: the chunks go to
  // the file as they are (H5Dwrite_chunk), without HDF5's copy through its
  // chunk cache, on one thread the writer's limit (docs/notebook/benchmarks-history.md).
  if (gzip == 0 && H5Tequal(mem_type, file_type) > 0) {
    const size_t row_bytes = size_t(H5Tget_size(file_type)) * size_t(total / dims[0]);
    std::vector<char> last;  // the final chunk, padded to its full size
    std::vector<hsize_t> offset(dims.size(), 0);
    for (hsize_t r = 0; r < dims[0]; r += chunk_rows) {
      offset[0] = r;
      const hsize_t rows = std::min(chunk_rows, dims[0] - r);
      const char* src = static_cast<const char*>(data) + size_t(r) * row_bytes;
      if (rows < chunk_rows) {
        last.assign(size_t(chunk_rows) * row_bytes, 0);
        std::memcpy(last.data(), src, size_t(rows) * row_bytes);
        src = last.data();
      }
      if (H5Dwrite_chunk(d.id, H5P_DEFAULT, 0, offset.data(), size_t(chunk_rows) * row_bytes, src) < 0)
        fail(path, std::string("writing dataset ") + name);
    }
    return;
  }
  if (H5Dwrite(d.id, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
    fail(path, std::string("writing dataset ") + name);
}

}  // namespace

// HDF5 truncates an existing file before it takes its lock (H5Fcreate with
// H5F_ACC_TRUNC opens it with O_TRUNC, then flock fails): a second run
// exporting to the file of a run still writing it emptied that file and
// failed, and the first run went on to finish a corrupt one. So the lock that
// HDF5 would take (flock, exclusive) is tried first on a descriptor of our
// own, and given back at once.
void h5::refuse_export_path(const std::string& path) {
  if (xdmf_path(path) == path)  // the sidecar would be renamed over the export, its frames lost
    throw FrameFileError(path + ": that is the name of the XDMF sidecar written next to the export (NAME.xmf "
                         "beside NAME.h5); give the export another extension, e.g. .h5");
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;  // no such file yet (or unreadable: H5Fcreate says so)
  const bool busy = ::flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);
  if (busy)
    throw FrameFileError(path + ": in use by another process (a run still writing it, or a program reading it); "
                         "not overwritten");
}

void h5::write_file_header(hid_t file, const FileHeader& header, const std::string& path) {
  attr_string(file, "format", kFramesFormat, path);
  const int version = kFramesFormatVersion;
  attr_array(file, "format_version", H5T_NATIVE_INT, H5T_STD_I32LE, &version, 1, path);
  attr_string(file, "scene", header.scene_json, path);
  attr_string(file, "sphray_version", header.version, path);
  attr_string(file, "backend", header.backend, path);
  Handle f{check(H5Gcreate2(file, "frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path, "creating /frames"),
           H5Gclose};
}

hid_t h5::create_frame_group(hid_t file, const std::string& name, double time, double dt, uint64_t step,
                             const std::string& path) {
  Handle frames{check(H5Gopen2(file, "frames", H5P_DEFAULT), path, "opening /frames"), H5Gclose};
  Handle g{check(H5Gcreate2(frames.id, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path,
                 "creating /frames/" + name),
           H5Gclose};
  attr_double(g.id, "time", time, path);
  attr_double(g.id, "dt", dt, path);
  attr_array(g.id, "step", H5T_NATIVE_UINT64, H5T_STD_U64LE, &step, 1, path);
  const hid_t id = g.id;
  g.id = -1;  // the caller's now
  return id;
}

XdmfFrame xdmf_frame_of(const Frame& f) {
  return {f.time,
          f.count(),
          !f.velocity.empty(),
          !f.density.empty(),
          !f.pressure.empty(),
          !f.presence.empty(),
          !f.field.empty(),
          {f.field_dims[0], f.field_dims[1], f.field_dims[2]},
          {f.field_origin[0], f.field_origin[1], f.field_origin[2]},
          f.field_voxel};
}

void check_frame_space(const std::string& path, const std::string& name, const std::vector<size_t>& values,
                       double sidecar_bytes, size_t written) {
  double payload = 0, padding = 0;
  for (const size_t v : values) {
    payload += 4.0 * double(v);
    padding += std::min(4.0 * double(v), 1048576.0);  // the last chunk is stored whole (under 1 MiB)
  }
  // chunk indexes, group, attributes; and the sidecar's rewrite (its .tmp beside the old one)
  const double need = 1.1 * payload + padding + 64.0 * 1024.0 + sidecar_bytes + 16.0 * 1024.0;
  struct statvfs fs {};
  if (statvfs(directory_of(path).c_str(), &fs) == 0 && double(fs.f_bavail) * double(fs.f_frsize) < need) {
    std::ostringstream os;
    os.precision(3);
    os << path << ": not enough free space for frame " << name << " (needs about " << need / 1048576.0 << " MiB, "
       << double(fs.f_bavail) * double(fs.f_frsize) / 1048576.0 << " MiB free); the file holds the " << written
       << " frames written before";
    throw FrameFileError(os.str());
  }
}

void XdmfSidecar::add(const XdmfFrame& f) {
  frames_.push_back(f);
  // Rewritten after every frame, a long run's sidecars would sum to the
  // square of its frame count; so paced (the rewrites sum to about 17 sidecars).
  const size_t behind = frames_.size() - written_;
  if (behind >= std::max<size_t>(1, written_ / 16) || std::chrono::steady_clock::now() - time_ > std::chrono::seconds(1))
    write();
}

void XdmfSidecar::finish() {
  if (written_ < frames_.size()) write();
}

void XdmfSidecar::write() {
  const std::string xmf = xdmf_path(h5_), tmp = xmf + ".tmp";
  const size_t slash = h5_.rfind('/');
  errno = 0;
  std::ofstream o(tmp);
  write_xdmf_document(o, slash == std::string::npos ? h5_ : h5_.substr(slash + 1), boundary_, frames_);
  const double bytes = double(o.tellp());
  o.close();
  if (!o || std::rename(tmp.c_str(), xmf.c_str()) != 0)
    throw FrameFileError(xmf + ": cannot write the XDMF sidecar: " + std::strerror(errno));
  written_ = frames_.size();
  ++writes_;
  bytes_ = bytes;
  time_ = std::chrono::steady_clock::now();
}

// ---------------- writer ----------------

FrameWriter::FrameWriter(const std::string& path, const FileHeader& header, int gzip) : path_(path), gzip_(gzip) {
  h5::refuse_export_path(path);
  errno = 0;
  Handle fapl{check(H5Pcreate(H5P_FILE_ACCESS), path, "property list"), H5Pclose};
  // The 1.8 file format: readable by every HDF5 >= 1.8 (h5py, ParaView).
  H5Pset_libver_bounds(fapl.id, H5F_LIBVER_V18, H5F_LIBVER_V18);
  file_ = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.id);
  if (file_ < 0) fail(path, "cannot create the export file");
  try {
    h5::write_file_header(file_, header, path);
    Handle g{check(H5Gcreate2(file_, "boundary", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path, "creating /boundary"),
             H5Gclose};
    const size_t boundary = header.boundary.size() / 3;
    dataset(g.id, "position", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, header.boundary.data(), {hsize_t(boundary), 3},
            gzip_, path);
    xdmf_ = std::make_unique<XdmfSidecar>(path, boundary);
    if (H5Fflush(file_, H5F_SCOPE_GLOBAL) < 0) fail(path, "flushing the header");
  } catch (...) {
    H5Fclose(file_);
    throw;
  }
  // the HDF5 error stack setting is per thread
  queue_ = std::make_unique<BackgroundQueue>([] { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); });
}

FrameWriter::~FrameWriter() {
  try {
    finish();
  } catch (...) {  // reported by an explicit finish(); a destructor must not throw
  }
}

void FrameWriter::submit(Frame&& f) {
  auto shared = std::make_shared<Frame>(std::move(f));
  submit(std::function<std::shared_ptr<const Frame>()>([shared] { return shared; }));
}

void FrameWriter::submit(std::function<std::shared_ptr<const Frame>()> f) {
  if (!queue_->submit([this, make = std::move(f)] { write(*make()); })) throw FrameFileError(queue_->error());
}

void FrameWriter::finish() {
  if (!queue_ || file_ < 0) {
    if (queue_ && queue_->failed()) throw FrameFileError(queue_->error());
    return;
  }
  const bool ok = queue_->finish();
  // After a failed write the file is left as the last good flush left it:
  // closing would flush the failed frame's partial metadata over it.
  if (ok) H5Fclose(file_);
  file_ = -1;
  if (!ok) {
    try {  // the frames written before, if the disk still takes the sidecar
      xdmf_->finish();
    } catch (const FrameFileError&) {
    }
    throw FrameFileError(queue_->error());
  }
  xdmf_->finish();
}

void FrameWriter::write(const Frame& f) {
  errno = 0;
  const std::string name = frame_name(xdmf_->frames());
  check_frame_space(path_, name,
                    {f.id.size(), f.position.size(), f.velocity.size(), f.density.size(), f.pressure.size(),
                     f.presence.size(), f.field.size()},
                    xdmf_->bytes(), xdmf_->frames());
  Handle g{h5::create_frame_group(file_, name, f.time, f.dt, f.step, path_), H5Gclose};
  const hsize_t n = f.count();
  dataset(g.id, "id", H5T_NATIVE_UINT32, H5T_STD_U32LE, f.id.data(), {n}, gzip_, path_);
  dataset(g.id, "position", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.position.data(), {n, 3}, gzip_, path_);
  if (!f.velocity.empty())
    dataset(g.id, "velocity", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.velocity.data(), {n, 3}, gzip_, path_);
  if (!f.density.empty())
    dataset(g.id, "density", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.density.data(), {n}, gzip_, path_);
  if (!f.pressure.empty())
    dataset(g.id, "pressure", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.pressure.data(), {n}, gzip_, path_);
  if (!f.presence.empty())
    dataset(g.id, "presence", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.presence.data(), {n, 6}, gzip_, path_);
  if (!f.field.empty()) {
    const std::vector<hsize_t> dims = {hsize_t(f.field_dims[2]), hsize_t(f.field_dims[1]), hsize_t(f.field_dims[0])};
    dataset(g.id, "field", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.field.data(), dims, gzip_, path_);
    Handle d{check(H5Dopen2(g.id, "field", H5P_DEFAULT), path_, "opening field"), H5Dclose};
    attr_array(d.id, "origin", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.field_origin, 3, path_);
    attr_array(d.id, "voxel_size", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, &f.field_voxel, 1, path_);
    attr_array(d.id, "iso", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, &f.field_iso, 1, path_);
  }
  for (const Frame::Skin& k : f.skins) {
    const hsize_t n = hsize_t(k.n);
    dataset(g.id, ("skin_" + std::to_string(k.obstacle)).c_str(), H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, k.height.data(),
            {6, n, n}, gzip_, path_);
  }
  if (H5Fflush(file_, H5F_SCOPE_GLOBAL) < 0) fail(path_, "flushing frame " + name);
  xdmf_->add(xdmf_frame_of(f));
}

}  // namespace sphray
