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

namespace sphray {

const char* sphray_version() { return SPHRAY_VERSION; }

std::string xdmf_path(const std::string& h5) {
  const size_t dot = h5.rfind('.'), slash = h5.rfind('/');
  const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash);
  return (has_ext ? h5.substr(0, dot) : h5) + ".xmf";
}

const std::vector<std::string>& exportable_fields() {
  static const std::vector<std::string> f = {"velocity", "density", "pressure", "presence", "field"};
  return f;
}

namespace {

// The HDF5 library prints its error stack itself unless told not to; sphray
// reports one message of its own instead, built from the stack's innermost
// entries and errno.
// Also: no library shutdown at exit. After a failed write sphray leaves the
// file unclosed, so that nothing more reaches the disk than the last good
// flush; HDF5's own exit handler would try to flush and close it.
struct QuietHdf5 {
  QuietHdf5() {
    H5dont_atexit();
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  }
};
const QuietHdf5 quiet_hdf5;

// An entry's description up to its details: "unable to open file: time = <a
// ctime string with its newline>, name = ..., tent_flags = 13" reads
// "unable to open file" (the path and errno are in the message already).
std::string error_summary(const char* desc) {
  std::string d(desc);
  d = d.substr(0, d.find('\n'));
  const size_t details = d.find(": time = ");
  return details == std::string::npos ? d : d.substr(0, details);
}

herr_t collect_error(unsigned n, const H5E_error2_t* e, void* out) {
  auto* s = static_cast<std::string*>(out);
  if (n < 2 && e->desc && *e->desc) *s += std::string(s->empty() ? "" : "; ") + error_summary(e->desc);
  return 0;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  std::string stack;
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_DOWNWARD, collect_error, &stack);
  const int err = errno;
  std::ostringstream os;
  os << path << ": " << what;
  if (err != 0) os << ": " << std::strerror(err);
  if (!stack.empty()) os << " (HDF5: " << stack << ")";
  H5Eclear2(H5E_DEFAULT);
  throw FrameFileError(os.str());
}

hid_t check(hid_t id, const std::string& path, const std::string& what) {
  if (id < 0) fail(path, what);
  return id;
}

// Closes an HDF5 handle at scope exit.
struct Handle {
  hid_t id;
  herr_t (*close)(hid_t);
  ~Handle() {
    if (id >= 0) close(id);
  }
};

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
  // chunk cache, which held the writer to about 2 GB/s (1.7x faster here).
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

std::string frame_name(size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%06zu", k);
  return buf;
}

// HDF5 truncates an existing file before it takes its lock (H5Fcreate with
// H5F_ACC_TRUNC opens it with O_TRUNC, then flock fails): a second run
// exporting to the file of a run still writing it emptied that file and
// failed, and the first run went on to finish a corrupt one. So the lock that
// HDF5 would take (flock, exclusive) is tried first on a descriptor of our
// own, and given back at once.
void refuse_if_in_use(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;  // no such file yet (or unreadable: H5Fcreate says so)
  const bool busy = ::flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  ::close(fd);
  if (busy)
    throw FrameFileError(path + ": in use by another process (a run still writing it, or a program reading it); "
                         "not overwritten");
}

}  // namespace

// ---------------- writer ----------------

FrameWriter::FrameWriter(const std::string& path, const FileHeader& header, int gzip) : path_(path), gzip_(gzip) {
  if (xdmf_path(path) == path)  // the sidecar would be renamed over the export, its frames lost
    throw FrameFileError(path + ": that is the name of the XDMF sidecar written next to the export (NAME.xmf "
                         "beside NAME.h5); give the export another extension, e.g. .h5");
  refuse_if_in_use(path);
  errno = 0;
  Handle fapl{check(H5Pcreate(H5P_FILE_ACCESS), path, "property list"), H5Pclose};
  // The 1.8 file format: readable by every HDF5 >= 1.8 (h5py, ParaView).
  H5Pset_libver_bounds(fapl.id, H5F_LIBVER_V18, H5F_LIBVER_V18);
  file_ = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.id);
  if (file_ < 0) fail(path, "cannot create the export file");
  try {
    attr_string(file_, "format", kFramesFormat, path);
    const int version = kFramesFormatVersion;
    attr_array(file_, "format_version", H5T_NATIVE_INT, H5T_STD_I32LE, &version, 1, path);
    attr_string(file_, "scene", header.scene_json, path);
    attr_string(file_, "sphray_version", header.version, path);
    attr_string(file_, "backend", header.backend, path);
    Handle g{check(H5Gcreate2(file_, "boundary", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path, "creating /boundary"),
             H5Gclose};
    boundary_ = header.boundary.size() / 3;
    dataset(g.id, "position", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, header.boundary.data(), {hsize_t(boundary_), 3},
            gzip_, path);
    Handle f{check(H5Gcreate2(file_, "frames", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path, "creating /frames"),
             H5Gclose};
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
      if (xdmf_written_ < xdmf_.size()) write_xdmf();
    } catch (const FrameFileError&) {
    }
    throw FrameFileError(queue_->error());
  }
  if (xdmf_written_ < xdmf_.size()) write_xdmf();
}

void FrameWriter::write(const Frame& f) {
  errno = 0;
  const std::string name = frame_name(xdmf_.size());
  // A frame that cannot fit is refused before the file is touched: a write
  // that fails half way (disk full) can leave HDF5's metadata inconsistent.
  double payload = 0, padding = 0;
  for (const size_t values : {f.id.size(), f.position.size(), f.velocity.size(), f.density.size(), f.pressure.size(),
                              f.presence.size(), f.field.size()}) {
    payload += 4.0 * double(values);
    padding += std::min(4.0 * double(values), 1048576.0);  // the last chunk is stored whole (under 1 MiB)
  }
  // chunk indexes, group, attributes; and the sidecar's rewrite (its .tmp beside the old one)
  const double need = 1.1 * payload + padding + 64.0 * 1024.0 + xdmf_bytes_ + 16.0 * 1024.0;
  struct statvfs fs {};
  const size_t slash = path_.rfind('/');
  const std::string dir = slash == std::string::npos ? "." : (slash == 0 ? "/" : path_.substr(0, slash));
  if (statvfs(dir.c_str(), &fs) == 0 && double(fs.f_bavail) * double(fs.f_frsize) < need) {
    std::ostringstream os;
    os.precision(3);
    os << path_ << ": not enough free space for frame " << name << " (needs about " << need / 1048576.0
       << " MiB, " << double(fs.f_bavail) * double(fs.f_frsize) / 1048576.0 << " MiB free); the file holds the "
       << xdmf_.size() << " frames written before";
    throw FrameFileError(os.str());
  }
  Handle frames{check(H5Gopen2(file_, "frames", H5P_DEFAULT), path_, "opening /frames"), H5Gclose};
  Handle g{check(H5Gcreate2(frames.id, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path_,
                 "creating /frames/" + name),
           H5Gclose};
  attr_double(g.id, "time", f.time, path_);
  attr_double(g.id, "dt", f.dt, path_);
  const uint64_t step = f.step;
  attr_array(g.id, "step", H5T_NATIVE_UINT64, H5T_STD_U64LE, &step, 1, path_);
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
  if (H5Fflush(file_, H5F_SCOPE_GLOBAL) < 0) fail(path_, "flushing frame " + name);
  xdmf_.push_back({f.time,
                   f.count(),
                   !f.velocity.empty(),
                   !f.density.empty(),
                   !f.pressure.empty(),
                   !f.presence.empty(),
                   !f.field.empty(),
                   {f.field_dims[0], f.field_dims[1], f.field_dims[2]},
                   {f.field_origin[0], f.field_origin[1], f.field_origin[2]},
                   f.field_voxel});
  // The sidecar is rewritten whole (to a .tmp renamed into place, so it is
  // never seen half written), and it grows with the frames: rewritten after
  // every frame, a long run's sidecars would sum to the square of its frame
  // count. So after every frame up to 16, then once the frames not yet in it
  // reach 1/16 of those in it (the rewrites sum to about 17 sidecars), or a
  // second has passed; and at the end.
  const size_t behind = xdmf_.size() - xdmf_written_;
  if (behind >= std::max<size_t>(1, xdmf_written_ / 16) ||
      std::chrono::steady_clock::now() - xdmf_time_ > std::chrono::seconds(1))
    write_xdmf();
}

// The sidecar that lets ParaView (and VisIt) read the export as time series:
// the particles with every per-particle dataset as a point array, the walls
// (the same particles at every time), and the density
// field, when exported, as a uniform grid of its voxel centres (contour it at
// the dataset's iso for the liquid's surface).
void FrameWriter::write_xdmf() {
  const std::string xmf = xdmf_path(path_), tmp = xmf + ".tmp";
  const size_t slash = path_.rfind('/');
  const std::string h5 = slash == std::string::npos ? path_ : path_.substr(slash + 1);
  std::ofstream o(tmp);
  o.precision(10);
  auto item = [&](const std::string& dims, const char* type, const std::string& path) {
    o << "<DataItem Dimensions=\"" << dims << "\" NumberType=\"" << type << "\" Precision=\"4\" Format=\"HDF\">" << h5
      << ":" << path << "</DataItem>";
  };
  auto attribute = [&](const char* name, const char* kind, const std::string& dims, const std::string& path,
                       const char* type = "Float") {
    o << "    <Attribute Name=\"" << name << "\" AttributeType=\"" << kind << "\" Center=\"Node\">\n     ";
    item(dims, type, path);
    o << "\n    </Attribute>\n";
  };
  o << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n <Domain>\n";
  // The walls at every frame's time, all from the one dataset: ParaView's
  // Xdmf3 readers drop a grid without a time from a file with time steps.
  if (boundary_ > 0) {
    const std::string b = std::to_string(boundary_);
    o << "  <Grid Name=\"walls\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (size_t k = 0; k < xdmf_.size(); ++k) {
      o << "   <Grid Name=\"walls " << k << "\" GridType=\"Uniform\">\n"
        << "    <Time Value=\"" << xdmf_[k].time << "\"/>\n"
        << "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << b << "\"/>\n"
        << "    <Geometry GeometryType=\"XYZ\">\n     ";
      item(b + " 3", "Float", "/boundary/position");
      o << "\n    </Geometry>\n   </Grid>\n";
    }
    o << "  </Grid>\n";
  }
  o << "  <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (size_t k = 0; k < xdmf_.size(); ++k) {
    const XdmfFrame& x = xdmf_[k];
    const std::string g = "/frames/" + frame_name(k), n = std::to_string(x.particles);
    o << "   <Grid Name=\"frame " << k << "\" GridType=\"Uniform\">\n"
      << "    <Time Value=\"" << x.time << "\"/>\n"
      << "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n << "\"/>\n"
      << "    <Geometry GeometryType=\"XYZ\">\n     ";
    item(n + " 3", "Float", g + "/position");
    o << "\n    </Geometry>\n";
    attribute("id", "Scalar", n, g + "/id", "UInt");
    if (x.velocity) attribute("velocity", "Vector", n + " 3", g + "/velocity");
    if (x.density) attribute("density", "Scalar", n, g + "/density");
    if (x.pressure) attribute("pressure", "Scalar", n, g + "/pressure");
    // six components, +x -x +y -y +z -z (ParaView's reader skips a HyperSlab per column)
    if (x.presence) attribute("presence", "Matrix", n + " 6", g + "/presence");
    o << "   </Grid>\n";
  }
  o << "  </Grid>\n";
  bool any_field = false;
  for (const XdmfFrame& x : xdmf_) any_field = any_field || x.field;
  if (any_field) {
    o << "  <Grid Name=\"field\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (size_t k = 0; k < xdmf_.size(); ++k) {
      const XdmfFrame& x = xdmf_[k];
      if (!x.field) continue;
      // XDMF orders a structured grid's axes slowest first: z, y, x, as the dataset is stored.
      const std::string dims = std::to_string(x.field_dims[2]) + " " + std::to_string(x.field_dims[1]) + " " +
                               std::to_string(x.field_dims[0]);
      const float v = x.field_voxel;  // values sit at voxel centres, half a voxel in from `origin`
      o << "   <Grid Name=\"field " << k << "\" GridType=\"Uniform\">\n"
        << "    <Time Value=\"" << x.time << "\"/>\n"
        << "    <Topology TopologyType=\"3DCoRectMesh\" Dimensions=\"" << dims << "\"/>\n"
        << "    <Geometry GeometryType=\"ORIGIN_DXDYDZ\">\n"
        << "     <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"4\" Format=\"XML\">"
        << x.field_origin[2] + 0.5f * v << " " << x.field_origin[1] + 0.5f * v << " " << x.field_origin[0] + 0.5f * v
        << "</DataItem>\n"
        << "     <DataItem Dimensions=\"3\" NumberType=\"Float\" Precision=\"4\" Format=\"XML\">" << v << " " << v
        << " " << v << "</DataItem>\n    </Geometry>\n";
      attribute("field", "Scalar", dims, "/frames/" + frame_name(k) + "/field");
      o << "   </Grid>\n";
    }
    o << "  </Grid>\n";
  }
  o << " </Domain>\n</Xdmf>\n";
  const double bytes = double(o.tellp());
  o.close();
  if (!o || std::rename(tmp.c_str(), xmf.c_str()) != 0)
    throw FrameFileError(xmf + ": cannot write the XDMF sidecar: " + std::strerror(errno));
  xdmf_written_ = xdmf_.size();
  ++xdmf_writes_;
  xdmf_bytes_ = bytes;
  xdmf_time_ = std::chrono::steady_clock::now();
}

// ---------------- reader ----------------

namespace {

std::string read_attr_string(hid_t loc, const char* name, const std::string& path) {
  if (H5Aexists(loc, name) <= 0) return {};
  Handle a{check(H5Aopen(loc, name, H5P_DEFAULT), path, std::string("opening attribute ") + name), H5Aclose};
  Handle ftype{check(H5Aget_type(a.id), path, "attribute type"), H5Tclose};
  if (H5Tget_class(ftype.id) != H5T_STRING) return {};
  if (H5Tis_variable_str(ftype.id) > 0) {
    Handle mtype{H5Tcopy(H5T_C_S1), H5Tclose};
    H5Tset_size(mtype.id, H5T_VARIABLE);
    H5Tset_cset(mtype.id, H5Tget_cset(ftype.id));
    char* p = nullptr;
    if (H5Aread(a.id, mtype.id, &p) < 0) fail(path, std::string("reading attribute ") + name);
    std::string s = p ? p : "";
    H5free_memory(p);
    return s;
  }
  const size_t n = H5Tget_size(ftype.id);
  std::string s(n, '\0');
  if (H5Aread(a.id, ftype.id, s.data()) < 0) fail(path, std::string("reading attribute ") + name);
  return s.substr(0, s.find('\0'));
}

template <class T>
T read_attr(hid_t loc, const char* name, hid_t mem_type, const std::string& path) {
  T v{};
  Handle a{check(H5Aopen(loc, name, H5P_DEFAULT), path, std::string("attribute ") + name + " missing"), H5Aclose};
  if (H5Aread(a.id, mem_type, &v) < 0) fail(path, std::string("reading attribute ") + name);
  return v;
}

std::vector<hsize_t> dims_of(hid_t d) {
  Handle s{H5Dget_space(d), H5Sclose};
  std::vector<hsize_t> dims(size_t(std::max(0, H5Sget_simple_extent_ndims(s.id))));
  H5Sget_simple_extent_dims(s.id, dims.data(), nullptr);
  return dims;
}

template <class T>
std::vector<T> read_dataset(hid_t loc, const char* name, hid_t mem_type, const std::string& path,
                            std::vector<hsize_t>* dims_out = nullptr) {
  Handle d{check(H5Dopen2(loc, name, H5P_DEFAULT), path, std::string("opening dataset ") + name), H5Dclose};
  const std::vector<hsize_t> dims = dims_of(d.id);
  size_t total = 1;
  for (hsize_t x : dims) total *= size_t(x);
  std::vector<T> v(total);
  if (total && H5Dread(d.id, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) < 0)
    fail(path, std::string("reading dataset ") + name);
  if (dims_out) *dims_out = dims;
  return v;
}

herr_t collect_name(hid_t, const char* name, const H5L_info_t*, void* out) {
  static_cast<std::vector<std::string>*>(out)->push_back(name);
  return 0;
}

std::vector<std::string> members(hid_t g) {
  std::vector<std::string> names;
  hsize_t idx = 0;
  H5Literate(g, H5_INDEX_NAME, H5_ITER_INC, &idx, collect_name, &names);
  return names;
}

}  // namespace

FrameReader::FrameReader(const std::string& path) : path_(path) {
  errno = 0;
  if (!std::ifstream(path, std::ios::binary)) throw FrameFileError(path + ": cannot open (missing or unreadable)");
  const htri_t is = H5Fis_hdf5(path.c_str());
  if (is == 0) throw FrameFileError(path + ": not an HDF5 file");
  file_ = is > 0 ? H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT) : -1;
  // HDF5 locks a file while a writer has it open: a run still exporting.
  if (file_ < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
    H5Eclear2(H5E_DEFAULT);
    throw FrameFileError(path + ": locked by another process (a run still writing it?). Wait for it to finish, or "
                         "read the frames flushed so far with HDF5_USE_FILE_LOCKING=FALSE set (a frame being written "
                         "at that moment may read as damaged)");
  }
  if (file_ < 0) fail(path, "cannot open as HDF5 (truncated or damaged file?)");
  try {
    const std::string format = read_attr_string(file_, "format", path);
    if (format != kFramesFormat)
      throw FrameFileError(path + ": an HDF5 file, but not a sphray frames file (root attribute format = \"" + format +
                           "\", expected \"" + kFramesFormat + "\")");
    version_ = read_attr<int>(file_, "format_version", H5T_NATIVE_INT, path);
    if (version_ > kFramesFormatVersion)
      throw FrameFileError(path + ": format_version " + std::to_string(version_) +
                           " is newer than this sphray reads (" + std::to_string(kFramesFormatVersion) + ")");
    header_.scene_json = read_attr_string(file_, "scene", path);
    header_.version = read_attr_string(file_, "sphray_version", path);
    header_.backend = read_attr_string(file_, "backend", path);
    if (H5Lexists(file_, "boundary", H5P_DEFAULT) > 0) {
      Handle b{check(H5Gopen2(file_, "boundary", H5P_DEFAULT), path, "opening /boundary"), H5Gclose};
      header_.boundary = read_dataset<float>(b.id, "position", H5T_NATIVE_FLOAT, path);
    }
    if (H5Lexists(file_, "frames", H5P_DEFAULT) <= 0) throw FrameFileError(path + ": no /frames group");
    Handle frames{check(H5Gopen2(file_, "frames", H5P_DEFAULT), path, "opening /frames"), H5Gclose};
    for (const std::string& name : members(frames.id)) {
      Handle g{check(H5Gopen2(frames.id, name.c_str(), H5P_DEFAULT), path, "opening /frames/" + name), H5Gclose};
      FrameInfo fi;
      fi.name = name;
      fi.time = read_attr<double>(g.id, "time", H5T_NATIVE_DOUBLE, path);
      fi.dt = read_attr<double>(g.id, "dt", H5T_NATIVE_DOUBLE, path);
      fi.step = read_attr<uint64_t>(g.id, "step", H5T_NATIVE_UINT64, path);
      fi.datasets = members(g.id);
      Handle d{check(H5Dopen2(g.id, "position", H5P_DEFAULT), path, "/frames/" + name + " has no position"),
               H5Dclose};
      const auto dims = dims_of(d.id);
      if (dims.size() != 2 || dims[1] != 3) throw FrameFileError(path + ": /frames/" + name + "/position is not N x 3");
      fi.particles = size_t(dims[0]);
      frames_.push_back(fi);
    }
  } catch (...) {
    H5Fclose(file_);
    throw;
  }
}

FrameReader::~FrameReader() {
  if (file_ >= 0) H5Fclose(file_);
}

Frame FrameReader::read(size_t k) const {
  const FrameInfo& fi = frames_.at(k);
  const std::string group = "/frames/" + fi.name, path = path_ + ": " + group;
  Handle g{check(H5Gopen2(file_, group.c_str(), H5P_DEFAULT), path, "opening"), H5Gclose};
  Frame f;
  f.time = fi.time;
  f.dt = fi.dt;
  f.step = fi.step;
  auto has = [&](const char* n) { return H5Lexists(g.id, n, H5P_DEFAULT) > 0; };
  if (has("id")) f.id = read_dataset<uint32_t>(g.id, "id", H5T_NATIVE_UINT32, path);
  f.position = read_dataset<float>(g.id, "position", H5T_NATIVE_FLOAT, path);
  if (has("velocity")) f.velocity = read_dataset<float>(g.id, "velocity", H5T_NATIVE_FLOAT, path);
  if (has("density")) f.density = read_dataset<float>(g.id, "density", H5T_NATIVE_FLOAT, path);
  if (has("pressure")) f.pressure = read_dataset<float>(g.id, "pressure", H5T_NATIVE_FLOAT, path);
  if (has("presence")) f.presence = read_dataset<float>(g.id, "presence", H5T_NATIVE_FLOAT, path);
  if (has("field")) {
    std::vector<hsize_t> dims;
    f.field = read_dataset<float>(g.id, "field", H5T_NATIVE_FLOAT, path, &dims);
    if (dims.size() != 3) throw FrameFileError(path + "/field: not a 3D grid (nz x ny x nx)");
    f.field_dims[0] = int(dims[2]);
    f.field_dims[1] = int(dims[1]);
    f.field_dims[2] = int(dims[0]);
    Handle d{check(H5Dopen2(g.id, "field", H5P_DEFAULT), path, "opening field"), H5Dclose};
    Handle a{check(H5Aopen(d.id, "origin", H5P_DEFAULT), path, "field origin"), H5Aclose};
    if (H5Aread(a.id, H5T_NATIVE_FLOAT, f.field_origin) < 0) fail(path, "reading attribute origin");
    f.field_voxel = read_attr<float>(d.id, "voxel_size", H5T_NATIVE_FLOAT, path);
    f.field_iso = read_attr<float>(d.id, "iso", H5T_NATIVE_FLOAT, path);
  }
  // Every per-particle dataset of the frame holds its particles (position is
  // N x 3, checked on opening; the field is a 3D grid, above): a reader
  // indexes them by particle.
  const size_t n = f.position.size() / 3;
  auto expect = [&](size_t values, size_t per_particle, const char* name) {
    if (values != 0 && values != n * per_particle)
      throw FrameFileError(path + "/" + name + ": " + std::to_string(values) + " values, expected " +
                           std::to_string(n * per_particle) + " (" + std::to_string(n) + " particles x " +
                           std::to_string(per_particle) + ")");
  };
  expect(f.id.size(), 1, "id");
  expect(f.velocity.size(), 3, "velocity");
  expect(f.density.size(), 1, "density");
  expect(f.pressure.size(), 1, "pressure");
  expect(f.presence.size(), 6, "presence");
  // Positions place particles in grids (render --from sorts them into one):
  // sphray never writes a non-finite one (a run stops first), so one is damage.
  for (size_t i = 0; i < f.position.size(); ++i)
    if (!std::isfinite(f.position[i]))
      throw FrameFileError(path + "/position: particle " + std::to_string(i / 3) + " has a non-finite " +
                           "xyz"[i % 3] + " (" + std::to_string(f.position[i]) + ")");
  if (f.id.size() != n) f.id.resize(n);
  return f;
}

}  // namespace sphray
