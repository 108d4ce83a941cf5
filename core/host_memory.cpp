#include "host_memory.h"

#include <atomic>
#include <cstdlib>
#include <new>

namespace sphray {

namespace {

void* malloc_acquire(size_t bytes) { return std::malloc(bytes); }
void malloc_release(void* p) { std::free(p); }

std::atomic<HostMemoryProvider*> g_provider{nullptr};

// Each block starts with a header holding the release of its provider, so a
// block made before a provider changed is still given back to the right one.
// 64 bytes keep the data as aligned as the block (cache lines, Float4).
constexpr size_t kHeader = 64;

}  // namespace

void set_pinned_provider(HostMemoryProvider p) {
  // Never freed: an allocation on another thread may still be reading the
  // one replaced (a backend installs one per process; tests a few).
  g_provider.store(new HostMemoryProvider(p));
}

HostMemoryProvider pinned_provider() {
  const HostMemoryProvider* prov = g_provider.load();
  return prov ? *prov : HostMemoryProvider{malloc_acquire, malloc_release};
}

void* pinned_alloc(size_t bytes) {
  HostMemoryProvider use = pinned_provider();
  void* block = use.acquire(bytes + kHeader);
  if (!block && use.acquire != malloc_acquire) {  // no page-locked memory left: ordinary memory
    use = {malloc_acquire, malloc_release};
    block = use.acquire(bytes + kHeader);
  }
  if (!block) throw std::bad_alloc();
  *static_cast<void (**)(void*)>(block) = use.release;
  return static_cast<char*>(block) + kHeader;
}

void pinned_free(void* p) {
  if (!p) return;
  void* block = static_cast<char*>(p) - kHeader;
  (*static_cast<void (**)(void*)>(block))(block);
}

}  // namespace sphray
