#include "kernel_times.h"

#include <atomic>
#include <mutex>

namespace sphray {

namespace {
std::atomic<bool> g_on{false};
std::mutex g_mutex;
std::vector<KernelTime> g_times;
PendingKernelTimes g_pending = nullptr;
}  // namespace

void set_kernel_timing(bool on) { g_on = on; }
bool kernel_timing() { return g_on; }

void add_kernel_time(const char* name, double ms) {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (KernelTime& k : g_times)
    if (k.name == name) {
      k.ms += ms;
      ++k.launches;
      return;
    }
  g_times.push_back({name, ms, 1});
}

void set_pending_kernel_times(PendingKernelTimes resolve) { g_pending = resolve; }

std::vector<KernelTime> take_kernel_times() {
  if (g_pending) g_pending();
  std::lock_guard<std::mutex> lock(g_mutex);
  std::vector<KernelTime> out;
  out.swap(g_times);
  return out;
}

}  // namespace sphray
