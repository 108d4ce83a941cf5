// Host/device portability: the one place that knows whether nvcc is compiling.
// Every per-element function in cuda/ is SPHRAY_HD so the CPU backend runs the
// exact code the GPU runs (DESIGN.md, "one source, two targets").
#pragma once

#if defined(__CUDACC__)
#define SPHRAY_HD __host__ __device__
#define SPHRAY_FORCEINLINE __forceinline__
#else
#define SPHRAY_HD
#define SPHRAY_FORCEINLINE inline
#endif
