// Device time per named launch (parallel_for("name", ...)), summed by name
// while kernel timing is on: CUDA events around each launch on the CUDA
// backend, the steady clock on the CPU. Off by default (the events cost a
// little per launch); `sphray bench sim --kernels` turns it on.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace sphray {

struct KernelTime {
  std::string name;
  double ms = 0;          // summed over the launches
  uint64_t launches = 0;
};

void set_kernel_timing(bool on);
bool kernel_timing();
// Adds a launch's time (the backends call it).
void add_kernel_time(const char* name, double ms);
// The times since the last call, by first launch; waits for pending CUDA
// launches. Clears them.
std::vector<KernelTime> take_kernel_times();

// The CUDA backend's hook: resolves the events it recorded (set by the
// backend when it times; null otherwise).
using PendingKernelTimes = void (*)();
void set_pending_kernel_times(PendingKernelTimes resolve);

}  // namespace sphray
