#include "rank_export.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <vector>

#if defined(SPHRAY_PARALLEL_HDF5)
#include <hdf5.h>
#include <mpi.h>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include "io/h5.h"
#endif

namespace sphray {

int IdBlocks::owner(uint32_t id) const {
  int r = int(std::min<uint64_t>(uint64_t(ranks) - 1, uint64_t(id) * uint64_t(ranks) / std::max<uint64_t>(m, 1)));
  while (r > 0 && lo(r) > id) --r;
  while (r + 1 < ranks && lo(r + 1) <= id) ++r;
  return r;
}

std::string rank_export_refusal(const std::set<std::string>& fields, int gzip) {
  if (fields.count("field")) return "--export-fields field is built on rank 0 alone";
  if (gzip > 0) return "export.gzip compresses on rank 0 alone";
  return {};
}

#if !defined(SPHRAY_PARALLEL_HDF5)

bool parallel_hdf5_built() { return false; }

struct RankFrameWriter::Impl {};

RankFrameWriter::RankFrameWriter(const std::string&, const FileHeader&, Comm&) {
  throw std::logic_error("this sphray was built without parallel HDF5");
}
RankFrameWriter::~RankFrameWriter() = default;
void RankFrameWriter::write(const Solver&, const SphParams&, const std::set<std::string>&) {}
void RankFrameWriter::finish() {}

#else

bool parallel_hdf5_built() { return true; }

using h5::check;
using h5::fail;
using h5::Handle;

namespace {

// A particle on its way to the rank that writes it.
struct Record {
  uint32_t id;
  float pos[3], vel[3], density;
};

// Collective: rank 0's message (empty: none) on every rank, thrown there as a FrameFileError.
void raise_from_root(Comm& comm, std::string message) {
  comm.broadcast(message, 0);
  if (!message.empty()) throw FrameFileError(message);
}

// Collective: the dataset `name` of `total` rows x `cols` (1: one
// dimension), contiguous, and this rank's `count` rows from row `first`.
void write_rows(hid_t loc, const char* name, hid_t mem_type, hid_t file_type, const void* data, hsize_t total,
                hsize_t cols, hsize_t first, hsize_t count, hid_t dxpl, const std::string& path) {
  const int dims_n = cols == 1 ? 1 : 2;
  const hsize_t dims[2] = {total, cols};
  Handle file_space{check(H5Screate_simple(dims_n, dims, nullptr), path, "dataspace"), H5Sclose};
  Handle dcpl{check(H5Pcreate(H5P_DATASET_CREATE), path, "property list"), H5Pclose};
  H5Pset_fill_time(dcpl.id, H5D_FILL_TIME_NEVER);  // every row is written
  Handle d{check(H5Dcreate2(loc, name, file_type, file_space.id, H5P_DEFAULT, dcpl.id, H5P_DEFAULT), path,
                 std::string("creating dataset ") + name),
           H5Dclose};
  if (total == 0) return;
  const hsize_t start[2] = {first, 0}, block[2] = {count, cols};
  Handle mem_space{check(H5Screate_simple(dims_n, block, nullptr), path, "dataspace"), H5Sclose};
  if (count > 0) {
    H5Sselect_hyperslab(file_space.id, H5S_SELECT_SET, start, nullptr, block, nullptr);
  } else {  // still part of the collective write
    H5Sselect_none(file_space.id);
    H5Sselect_none(mem_space.id);
  }
  if (H5Dwrite(d.id, mem_type, mem_space.id, file_space.id, dxpl, data) < 0)
    fail(path, std::string("writing dataset ") + name);
}

}  // namespace

struct RankFrameWriter::Impl {
  std::string path;
  Comm& comm;
  hid_t file = -1, dxpl = -1, fapl = -1;
  int lock = -1;  // rank 0: the lock HDF5 takes on a file it writes, which MPI-IO does not take
  std::unique_ptr<XdmfSidecar> sidecar;  // rank 0's
  RawParticles raw;                      // this rank's own particles
  std::vector<char> out;                 // records by destination rank
  std::vector<int32_t> slot;             // the record of each id of this rank's block (-1: none)
  Frame rows;                            // this rank's rows

  Impl(const std::string& p, Comm& c) : path(p), comm(c) {}
  // Closed (its metadata written; every object in it closed before) and opened again.
  void reopen(const std::string& after) {
    const herr_t closed = H5Fclose(file);
    file = closed < 0 ? -1 : H5Fopen(path.c_str(), H5F_ACC_RDWR, fapl);
    if (file < 0) fail(path, "closing and reopening the file after " + after);
  }
  void close() {
    if (dxpl >= 0) H5Pclose(dxpl);
    if (fapl >= 0) H5Pclose(fapl);
    if (file >= 0) H5Fclose(file);
    if (lock >= 0) ::close(lock);
    dxpl = fapl = file = lock = -1;
  }
};

RankFrameWriter::RankFrameWriter(const std::string& path, const FileHeader& header, Comm& comm)
    : impl_(std::make_unique<Impl>(path, comm)) {
  Impl& m = *impl_;
  std::string refused;
  if (comm.rank() == 0) {
    try {
      h5::refuse_export_path(path);
      // MPI-IO reports a missing or read-only directory without errno's reason.
      if (::access(directory_of(path).c_str(), W_OK) != 0)
        throw FrameFileError(path + ": cannot create the export file: " + std::strerror(errno));
    } catch (const FrameFileError& e) {
      refused = e.what();
    }
  }
  raise_from_root(comm, refused);
  errno = 0;
  m.fapl = check(H5Pcreate(H5P_FILE_ACCESS), path, "property list");
  if (H5Pset_fapl_mpio(m.fapl, MPI_COMM_WORLD, MPI_INFO_NULL) < 0) {
    m.close();
    fail(path, "MPI-IO file access");
  }
  // Metadata read and written by all ranks together (one read per rank
  // count, not one per rank); the 1.8 format as FrameWriter writes it.
  H5Pset_all_coll_metadata_ops(m.fapl, true);
  H5Pset_coll_metadata_write(m.fapl, true);
  H5Pset_libver_bounds(m.fapl, H5F_LIBVER_V18, H5F_LIBVER_V18);
  m.file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, m.fapl);
  if (m.file < 0) {
    m.close();
    fail(path, "cannot create the export file");
  }
  // As FrameWriter's file is locked by HDF5: another run refuses to
  // overwrite it (h5::refuse_export_path), and readers that lock wait.
  if (comm.rank() == 0) {
    m.lock = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (m.lock >= 0) ::flock(m.lock, LOCK_EX | LOCK_NB);
  }
  try {
    m.dxpl = check(H5Pcreate(H5P_DATASET_XFER), path, "property list");
    H5Pset_dxpl_mpio(m.dxpl, H5FD_MPIO_COLLECTIVE);
    h5::write_file_header(m.file, header, path);
    const hsize_t boundary = header.boundary.size() / 3;
    {  // closed before the file is
      Handle g{check(H5Gcreate2(m.file, "boundary", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), path,
                     "creating /boundary"),
               H5Gclose};
      write_rows(g.id, "position", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, header.boundary.data(), boundary, 3, 0,
                 comm.rank() == 0 ? boundary : 0, m.dxpl, path);
    }
    m.reopen("the header");
    if (comm.rank() == 0) m.sidecar = std::make_unique<XdmfSidecar>(path, size_t(boundary));
  } catch (...) {
    m.close();
    throw;
  }
}

RankFrameWriter::~RankFrameWriter() {
  if (std::uncaught_exceptions() > 0) return;
  try {
    finish();
  } catch (...) {  // reported by an explicit finish(); a destructor must not throw
  }
}

void RankFrameWriter::finish() {
  if (!impl_ || impl_->file < 0) return;
  impl_->close();
  if (impl_->sidecar) impl_->sidecar->finish();
}

void RankFrameWriter::write(const Solver& s, const SphParams& prm, const std::set<std::string>& fields) {
  const auto t0 = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  Comm& comm = m.comm;
  const int ranks = comm.size(), me = comm.rank();
  const bool velocity = fields.count("velocity") > 0, density = fields.count("density") > 0,
             pressure = fields.count("pressure") > 0;
  s.download_owned(m.raw, velocity);
  if (m.raw.ready) m.raw.ready();
  const size_t n = m.raw.id.size();

  // The blocks of ids: 0 .. the largest id over the ranks (ids are the
  // particles' initial indices; removed particles leave gaps).
  uint32_t largest = 0;
  for (size_t i = 0; i < n; ++i) largest = std::max(largest, m.raw.id[i]);
  if (largest > uint32_t(INT32_MAX)) throw FrameFileError(m.path + ": particle ids beyond 2^31 - 1");
  int neg = -int(largest);
  comm.min(&neg, 1);
  const IdBlocks blocks{uint64_t(-int64_t(neg)) + 1, ranks};

  // Each particle to the rank of its id's block: one all-to-all of records
  // packed by destination.
  std::vector<int> send(size_t(ranks), 0), recv;
  for (size_t i = 0; i < n; ++i) send[size_t(blocks.owner(m.raw.id[i]))] += int(sizeof(Record));
  std::vector<size_t> at(size_t(ranks), 0);
  for (int r = 1; r < ranks; ++r) at[size_t(r)] = at[size_t(r - 1)] + size_t(send[size_t(r - 1)]);
  m.out.resize(n * sizeof(Record));
  for (size_t i = 0; i < n; ++i) {
    const int r = blocks.owner(m.raw.id[i]);
    const Float4 p = m.raw.pos[i];
    const Float4 v = velocity ? m.raw.vel[i] : Float4{0, 0, 0, 0};
    const Record rec{m.raw.id[i], {p.x, p.y, p.z}, {v.x, v.y, v.z}, p.w};
    std::memcpy(m.out.data() + at[size_t(r)], &rec, sizeof(Record));
    at[size_t(r)] += sizeof(Record);
  }
  const std::vector<char> in = comm.all_to_all(m.out, send, recv);

  // This rank's block in id order; its rows follow the lower blocks' rows.
  const uint64_t lo = blocks.lo(me), width = blocks.lo(me + 1) - lo;
  const size_t mine = in.size() / sizeof(Record);
  m.slot.assign(size_t(width), -1);
  for (size_t k = 0; k < mine; ++k) {
    uint32_t id;
    std::memcpy(&id, in.data() + k * sizeof(Record), sizeof id);
    m.slot[size_t(id - lo)] = int32_t(k);
  }
  std::vector<double> rows_of(size_t(ranks), 0.0);
  rows_of[size_t(me)] = double(mine);
  comm.sum(rows_of.data(), ranks);
  size_t first = 0, total = 0;
  for (int r = 0; r < ranks; ++r) {
    if (r < me) first += size_t(rows_of[size_t(r)]);
    total += size_t(rows_of[size_t(r)]);
  }
  Frame& f = m.rows;
  f.id.resize(mine);
  f.position.resize(3 * mine);
  f.velocity.resize(velocity ? 3 * mine : 0);
  f.density.resize(density ? mine : 0);
  f.pressure.resize(pressure ? mine : 0);
  size_t row = 0;
  for (size_t k = 0; k < size_t(width); ++k) {
    if (m.slot[k] < 0) continue;
    Record rec;
    std::memcpy(&rec, in.data() + size_t(m.slot[k]) * sizeof(Record), sizeof rec);
    f.id[row] = rec.id;
    std::copy(rec.pos, rec.pos + 3, &f.position[3 * row]);
    if (velocity) std::copy(rec.vel, rec.vel + 3, &f.velocity[3 * row]);
    if (density) f.density[row] = rec.density;
    if (pressure) f.pressure[row] = tait_pressure(prm, rec.density);
    ++row;
  }

  const std::string name = frame_name(frames_);
  std::string refused;
  if (me == 0) {
    try {
      check_frame_space(m.path, name,
                        {total, 3 * total, velocity ? 3 * total : 0, density ? total : 0, pressure ? total : 0},
                        m.sidecar->bytes(), frames_);
    } catch (const FrameFileError& e) {
      refused = e.what();
    }
  }
  raise_from_root(comm, refused);
  errno = 0;
  {
    Handle g{h5::create_frame_group(m.file, name, s.time(), s.last_limits().dt, s.steps(), m.path), H5Gclose};
    write_rows(g.id, "id", H5T_NATIVE_UINT32, H5T_STD_U32LE, f.id.data(), total, 1, first, mine, m.dxpl, m.path);
    write_rows(g.id, "position", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.position.data(), total, 3, first, mine, m.dxpl,
               m.path);
    if (velocity)
      write_rows(g.id, "velocity", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.velocity.data(), total, 3, first, mine, m.dxpl,
                 m.path);
    if (density)
      write_rows(g.id, "density", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.density.data(), total, 1, first, mine, m.dxpl,
                 m.path);
    if (pressure)
      write_rows(g.id, "pressure", H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, f.pressure.data(), total, 1, first, mine, m.dxpl,
                 m.path);
  }
  // The frame's metadata to the file, so that a run killed later leaves it
  // readable, as FrameWriter's H5Fflush does. Not H5Fflush here: over MPI-IO
  // it syncs the file to the disk (fsync), which took most of a frame's
  // time (docs/benchmarks.md); closing writes the metadata without it.
  m.reopen("frame " + name);
  if (me == 0) {
    XdmfFrame x{};
    x.time = s.time();
    x.particles = total;
    x.velocity = velocity;
    x.density = density;
    x.pressure = pressure;
    m.sidecar->add(x);
  }
  ++frames_;
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

#endif

}  // namespace sphray
