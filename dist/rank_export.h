// The HDF5 export of a run over several ranks written by every rank (parallel
// HDF5 over MPI-IO), instead of through rank 0: the same file, row k the
// particle of the k-th smallest id in every dataset (docs/formats.md). At
// each output frame every rank sends its own particles to the rank whose
// block of ids holds theirs (one all-to-all), orders its block by id and
// writes it as one hyperslab of each dataset; the groups, attributes and
// datasets are made by all ranks together, the XDMF sidecar by rank 0.
// Synchronous (MPI-IO's collective writes are made on the run's thread);
// the particle datasets only, uncompressed (rank_export_refusal): the field
// and gzip go through rank 0. Built where CMake finds a parallel HDF5
// (SPHRAY_PARALLEL_HDF5); what it costs against rank 0: docs/benchmarks.md,
// "Outputs of a run over several ranks".
#pragma once

#include <cstdint>
#include <memory>
#include <set>
#include <string>

#include "comm.h"
#include "io/frames_h5.h"
#include "sph/params.h"
#include "sph/solver.h"

namespace sphray {

// Whether this build links a parallel HDF5.
bool parallel_hdf5_built();

// The ids 0 .. m-1 cut into `ranks` consecutive blocks, rank r's
// [lo(r), lo(r + 1)): a frame's particles go to the rank of their id's block.
struct IdBlocks {
  uint64_t m = 0;
  int ranks = 1;
  uint64_t lo(int r) const { return m * uint64_t(r) / uint64_t(ranks); }
  int owner(uint32_t id) const;  // the r with lo(r) <= id < lo(r + 1)
};

// Why every rank cannot write an export of `fields` at deflate level `gzip`
// (empty when it can): the field is built on rank 0 alone, and compressed
// datasets are not written from several ranks here.
std::string rank_export_refusal(const std::set<std::string>& fields, int gzip);

class RankFrameWriter {
 public:
  // Collective: creates (truncates) `path` and writes its header (rank 0 the
  // wall particles' rows). Throws FrameFileError as FrameWriter does.
  RankFrameWriter(const std::string& path, const FileHeader& header, Comm& comm);
  // Closes the file (collective) unless an exception is unwinding: a rank
  // leaving on an error must not wait for the others (they end through
  // MPI_Abort); the frames flushed before stay readable.
  ~RankFrameWriter();
  RankFrameWriter(const RankFrameWriter&) = delete;
  RankFrameWriter& operator=(const RankFrameWriter&) = delete;

  // Collective: the frame of `s` (each rank's download_owned()) with the
  // particle datasets in `fields` (velocity, density, pressure).
  void write(const Solver& s, const SphParams& prm, const std::set<std::string>& fields);
  void finish();  // collective: closes the file; rank 0 completes the sidecar
  size_t frames_written() const { return frames_; }
  double seconds_writing() const { return seconds_; }  // the run's time in write()

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  size_t frames_ = 0;
  double seconds_ = 0;
};

}  // namespace sphray
