// Host/device portability: the one place that knows whether nvcc is compiling.
// Every per-element function is SPHRAY_HD so the CPU backend runs the
// exact code the GPU runs (docs/design.md, "One source, two backends").
#pragma once

#include <cstdint>
#include <cstring>

#if defined(__CUDACC__)
#define SPHRAY_HD __host__ __device__
#define SPHRAY_FORCEINLINE __forceinline__
#else
#define SPHRAY_HD
#define SPHRAY_FORCEINLINE inline
#endif

// Unrolls the loop that follows: in nvcc's device pass and in GCC (not in
// nvcc's host pass, whose front end does not know GCC's pragma).
#if defined(__CUDA_ARCH__)
#define SPHRAY_UNROLL _Pragma("unroll")
#elif defined(__GNUC__) && !defined(__clang__) && !defined(__CUDACC__)
#define SPHRAY_UNROLL _Pragma("GCC unroll 8")
#else
#define SPHRAY_UNROLL
#endif

namespace sphray {
// Threads per block of the CUDA backend's parallel_for (core/launch_cuda.cuh);
// per-warp shared-memory tiles (the pair-mask build) are sized by it.
constexpr unsigned kThreadsPerBlock = 128;

// A float's bit pattern and back (a value carried in a float's or a
// uint32's slot: packed normals, depth maps' atomic min/max).
SPHRAY_HD SPHRAY_FORCEINLINE float bits_to_float(uint32_t u) {
#if defined(__CUDA_ARCH__)
  return __uint_as_float(u);
#else
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
#endif
}
SPHRAY_HD SPHRAY_FORCEINLINE uint32_t float_to_bits(float f) {
#if defined(__CUDA_ARCH__)
  return __float_as_uint(f);
#else
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
#endif
}
}  // namespace sphray
