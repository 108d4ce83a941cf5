// Float atomics for host and device, so that scatter kernels (the field
// splats) are one source: CUDA's atomicAdd on the GPU, GCC's __atomic
// builtins on the bit pattern on the CPU (OpenMP threads).
#pragma once

#include <cstdint>
#include <cstring>

#include "hd.h"

namespace sphray {

SPHRAY_HD SPHRAY_FORCEINLINE float load_relaxed(const float* p) {
#if defined(__CUDA_ARCH__)
  return *reinterpret_cast<const volatile float*>(p);
#else
  uint32_t bits = __atomic_load_n(reinterpret_cast<const uint32_t*>(p), __ATOMIC_RELAXED);
  float v;
  std::memcpy(&v, &bits, sizeof v);
  return v;
#endif
}

// A read that may be stale: on the GPU a plain load, which the L1 cache may
// serve with a value older than the latest write of another thread; for
// words that only grow, or grow past a bound only for a moment, such a value
// errs low (the presence splat, field/builders.h).
SPHRAY_HD SPHRAY_FORCEINLINE float load_cached(const float* p) {
#if defined(__CUDA_ARCH__)
  return *p;
#else
  return load_relaxed(p);
#endif
}

SPHRAY_HD SPHRAY_FORCEINLINE void store_relaxed(float* p, float v) {
#if defined(__CUDA_ARCH__)
  *reinterpret_cast<volatile float*>(p) = v;
#else
  uint32_t bits;
  std::memcpy(&bits, &v, sizeof bits);
  __atomic_store_n(reinterpret_cast<uint32_t*>(p), bits, __ATOMIC_RELAXED);
#endif
}

// *p += v, returning the value before (one ATOM instruction on the GPU).
SPHRAY_HD SPHRAY_FORCEINLINE float atomic_fetch_add(float* p, float v) {
#if defined(__CUDA_ARCH__)
  return atomicAdd(p, v);
#else
  uint32_t* u = reinterpret_cast<uint32_t*>(p);
  uint32_t old = __atomic_load_n(u, __ATOMIC_RELAXED), next;
  float f;
  do {
    std::memcpy(&f, &old, sizeof f);
    const float g = f + v;
    std::memcpy(&next, &g, sizeof g);
  } while (!__atomic_compare_exchange_n(u, &old, next, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED));
  return f;
#endif
}

// *p += v. One RED instruction on the GPU (the return value is unused).
SPHRAY_HD SPHRAY_FORCEINLINE void atomic_add(float* p, float v) {
#if defined(__CUDA_ARCH__)
  atomicAdd(p, v);
#else
  atomic_fetch_add(p, v);
#endif
}

// *p = min(*p, v) and max, on unsigned integers (non-negative floats compare
// as their bit patterns do: the screen-space depth maps use that). Both read
// *p first and skip the atomic where v cannot change it (the common case when
// many writers race for one slot); on the GPU a plain load, which the L1
// cache can serve (a volatile load would go to L2 every time).
SPHRAY_HD SPHRAY_FORCEINLINE void atomic_min(uint32_t* p, uint32_t v) {
#if defined(__CUDA_ARCH__)
  if (v < *p) atomicMin(reinterpret_cast<unsigned int*>(p), v);
#else
  uint32_t old = __atomic_load_n(p, __ATOMIC_RELAXED);
  while (v < old && !__atomic_compare_exchange_n(p, &old, v, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
#endif
}

SPHRAY_HD SPHRAY_FORCEINLINE void atomic_max(uint32_t* p, uint32_t v) {
#if defined(__CUDA_ARCH__)
  if (v > *p) atomicMax(reinterpret_cast<unsigned int*>(p), v);
#else
  uint32_t old = __atomic_load_n(p, __ATOMIC_RELAXED);
  while (v > old && !__atomic_compare_exchange_n(p, &old, v, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED)) {
  }
#endif
}

// ++*p, unordered (counters read after the launch).
SPHRAY_HD SPHRAY_FORCEINLINE void atomic_increment(uint32_t* p) {
#if defined(__CUDA_ARCH__)
  atomicAdd(reinterpret_cast<unsigned int*>(p), 1u);
#else
  __atomic_fetch_add(p, 1u, __ATOMIC_RELAXED);
#endif
}

// ++*p, returning the value before, ordered after this thread's earlier
// writes (a release fence first) and before its later reads: the bottom-up
// passes (mesh/bvh_build.inl) let the second child to arrive read what the
// first one wrote.
SPHRAY_HD SPHRAY_FORCEINLINE uint32_t atomic_arrive(uint32_t* p) {
#if defined(__CUDA_ARCH__)
  __threadfence();
  const uint32_t old = atomicAdd(reinterpret_cast<unsigned int*>(p), 1u);
  __threadfence();
  return old;
#else
  return __atomic_fetch_add(p, 1u, __ATOMIC_ACQ_REL);
#endif
}

}  // namespace sphray
