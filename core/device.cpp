#include "device.h"

#include <stdexcept>

namespace sphray {

const char* backend_name(Backend b) { return b == Backend::Cuda ? "cuda" : "cpu"; }

void throw_no_cuda() {
  throw std::runtime_error("this sphray was built without CUDA (nvcc was not found at configure time); use --backend cpu");
}

#if !defined(SPHRAY_HAVE_CUDA)
bool cuda_available() { return false; }
std::string cuda_device_name() { return {}; }
size_t cuda_free_memory() { return 0; }
int cuda_device_count() { return 0; }
void use_cuda_device(int) { throw_no_cuda(); }
#endif

}  // namespace sphray
