// What the HDF5 frame writers (io/frames_h5.h; every rank's, dist/rank_export.h)
// and the reader share: one error message of sphray's own for a failed HDF5
// call, handles closed at scope exit, the file's header and a frame's group.
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <string>

namespace sphray {
struct FileHeader;
}

namespace sphray::h5 {

// Throws FrameFileError: "path: what: errno's reason (HDF5: its innermost
// errors)"; clears HDF5's error stack.
[[noreturn]] void fail(const std::string& path, const std::string& what);

// `id`, or fail(path, what) when the call that made it failed.
hid_t check(hid_t id, const std::string& path, const std::string& what);

// Closes an HDF5 handle at scope exit.
struct Handle {
  hid_t id;
  herr_t (*close)(hid_t);
  ~Handle() {
    if (id >= 0) close(id);
  }
};

// Throws FrameFileError when `path` cannot take an export: it is the name of
// its own XDMF sidecar, or another process holds it open for writing or
// reading (HDF5's lock; HDF5 would empty the file before it finds the lock
// taken).
void refuse_export_path(const std::string& path);

// The root attributes of an export (format, format_version, scene,
// sphray_version, backend) and its empty /frames group.
void write_file_header(hid_t file, const FileHeader& header, const std::string& path);

// /frames/`name`, with its time, dt and step attributes; closed by the caller.
hid_t create_frame_group(hid_t file, const std::string& name, double time, double dt, uint64_t step,
                         const std::string& path);

}  // namespace sphray::h5
