// Host/device portability: the one place that knows whether nvcc is compiling.
// Every per-element function is SPHRAY_HD so the CPU backend runs the
// exact code the GPU runs (docs/design.md, "One source, two backends").
#pragma once

#if defined(__CUDACC__)
#define SPHRAY_HD __host__ __device__
#define SPHRAY_FORCEINLINE __forceinline__
#else
#define SPHRAY_HD
#define SPHRAY_FORCEINLINE inline
#endif

namespace sphray {
// Threads per block of the CUDA backend's parallel_for (core/launch_cuda.cuh);
// per-warp shared-memory tiles (the pair-mask build) are sized by it.
constexpr unsigned kThreadsPerBlock = 128;
}  // namespace sphray
