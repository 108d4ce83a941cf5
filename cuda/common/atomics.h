// Float atomics for host and device, so that scatter kernels (the field
// splats) are one source: CUDA's atomicAdd / atomicCAS on the GPU, GCC's
// __atomic builtins on the bit pattern on the CPU (OpenMP threads).
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

// *p += v. One RED instruction on the GPU (the return value is unused).
SPHRAY_HD SPHRAY_FORCEINLINE void atomic_add(float* p, float v) {
#if defined(__CUDA_ARCH__)
  atomicAdd(p, v);
#else
  uint32_t* u = reinterpret_cast<uint32_t*>(p);
  uint32_t old = __atomic_load_n(u, __ATOMIC_RELAXED), next;
  do {
    float f;
    std::memcpy(&f, &old, sizeof f);
    f += v;
    std::memcpy(&next, &f, sizeof f);
  } while (!__atomic_compare_exchange_n(u, &old, next, true, __ATOMIC_RELAXED, __ATOMIC_RELAXED));
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

// Compare-and-swap on a float's bits: writes `desired` if *p still holds
// `expected`; returns the value found (== expected on success, bit for bit).
SPHRAY_HD SPHRAY_FORCEINLINE float atomic_cas(float* p, float expected, float desired) {
#if defined(__CUDA_ARCH__)
  const unsigned int found =
      atomicCAS(reinterpret_cast<unsigned int*>(p), __float_as_uint(expected), __float_as_uint(desired));
  return __uint_as_float(found);
#else
  uint32_t e, d;
  std::memcpy(&e, &expected, sizeof e);
  std::memcpy(&d, &desired, sizeof d);
  __atomic_compare_exchange_n(reinterpret_cast<uint32_t*>(p), &e, d, false, __ATOMIC_RELAXED, __ATOMIC_RELAXED);
  float found;
  std::memcpy(&found, &e, sizeof found);
  return found;
#endif
}

SPHRAY_HD SPHRAY_FORCEINLINE bool same_bits(float a, float b) {
#if defined(__CUDA_ARCH__)
  return __float_as_uint(a) == __float_as_uint(b);
#else
  uint32_t x, y;
  std::memcpy(&x, &a, sizeof x);
  std::memcpy(&y, &b, sizeof y);
  return x == y;
#endif
}

}  // namespace sphray
