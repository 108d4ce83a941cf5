// The CUDA device as the host sees it (a build with nvcc).
#include "device.h"
#include "launch_cuda.cuh"

namespace sphray {

bool cuda_available() {
  int count = 0;
  return cudaGetDeviceCount(&count) == cudaSuccess && count > 0;
}

int cuda_device_count() {
  int count = 0;
  return cudaGetDeviceCount(&count) == cudaSuccess ? count : 0;
}

void use_cuda_device(int k) { SPHRAY_CUDA_CHECK(cudaSetDevice(k)); }

std::string cuda_device_name() {
  if (!cuda_available()) return {};
  cudaDeviceProp prop{};
  int device = 0;
  SPHRAY_CUDA_CHECK(cudaGetDevice(&device));
  SPHRAY_CUDA_CHECK(cudaGetDeviceProperties(&prop, device));
  return prop.name;
}

size_t cuda_free_memory() {
  if (!cuda_available()) return 0;
  size_t free_b = 0, total_b = 0;
  SPHRAY_CUDA_CHECK(cudaMemGetInfo(&free_b, &total_b));
  return free_b;
}

}  // namespace sphray
