// Host buffers that a backend may page-lock. Device-to-host copies into
// pinned (page-locked) memory run at the bus's speed; into ordinary memory the
// driver stages them through a pinned buffer of its own at about half that.
// The export's snapshots (RawParticles, solver.h) use them: at 1M particles
// and a frame every 5 steps, the copy was what the run paid for exporting.
#pragma once

#include <cstddef>
#include <vector>

namespace sphray {

// Where pinned blocks come from. The default is ordinary memory (malloc); the
// CUDA backend installs cudaMallocHost once a device is in use. Every block
// remembers the `release` of the provider that made it.
struct HostMemoryProvider {
  void* (*acquire)(size_t bytes);  // null when it cannot
  void (*release)(void* p);
};
void set_pinned_provider(HostMemoryProvider p);
HostMemoryProvider pinned_provider();  // the one installed (malloc's when none)

void* pinned_alloc(size_t bytes);  // throws std::bad_alloc
void pinned_free(void* p);

template <class T>
struct PinnedAllocator {
  using value_type = T;
  PinnedAllocator() = default;
  template <class U>
  PinnedAllocator(const PinnedAllocator<U>&) {}
  T* allocate(size_t n) { return static_cast<T*>(pinned_alloc(n * sizeof(T))); }
  void deallocate(T* p, size_t) { pinned_free(p); }
  template <class U>
  bool operator==(const PinnedAllocator<U>&) const { return true; }
  template <class U>
  bool operator!=(const PinnedAllocator<U>&) const { return false; }
};

template <class T>
using PinnedVector = std::vector<T, PinnedAllocator<T>>;

}  // namespace sphray
