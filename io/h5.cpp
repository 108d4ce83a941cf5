#include "h5.h"

#include <cerrno>
#include <cstring>
#include <sstream>

#include "frames_h5.h"

namespace sphray::h5 {

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

}  // namespace

void fail(const std::string& path, const std::string& what) {
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

}  // namespace sphray::h5
