// The reader of HDF5 frame files (frames_h5.h).
#include <hdf5.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "frames_h5.h"
#include "h5.h"

namespace sphray {

using h5::check;
using h5::fail;
using h5::Handle;

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
  for (const std::string& name : fi.datasets) {
    if (name.rfind("skin_", 0) != 0) continue;
    Frame::Skin k;
    try {
      k.obstacle = uint32_t(std::stoul(name.substr(5)));
    } catch (const std::exception&) {
      throw FrameFileError(path + "/" + name + ": not skin_<obstacle index>");
    }
    std::vector<hsize_t> dims;
    k.height = read_dataset<float>(g.id, name.c_str(), H5T_NATIVE_FLOAT, path, &dims);
    if (dims.size() != 3 || dims[0] != 6 || dims[1] != dims[2])
      throw FrameFileError(path + "/" + name + ": not 6 x n x n skin heights");
    k.n = int(dims[1]);
    f.skins.push_back(std::move(k));
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
