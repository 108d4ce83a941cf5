// What the HDF5 frame writer and reader share (io/ only): one error message
// of sphray's own for a failed HDF5 call, and handles closed at scope exit.
#pragma once

#include <hdf5.h>

#include <string>

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

}  // namespace sphray::h5
