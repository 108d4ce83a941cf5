// CPU backend: the per-element functors run in an OpenMP loop, and
// sort/reduce go through Thrust's OpenMP system (docs/design.md, "One
// source, two backends").
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <functional>
#include <vector>

#include <thrust/iterator/counting_iterator.h>
#include <thrust/reduce.h>
#include <thrust/sequence.h>
#include <thrust/sort.h>
#include <thrust/binary_search.h>
#include <thrust/gather.h>
#include <thrust/copy.h>
#include <thrust/fill.h>
#include <thrust/count.h>
#include <thrust/transform_reduce.h>
#include <thrust/transform_scan.h>
#if defined(_OPENMP)
#include <thrust/system/omp/execution_policy.h>
#else
#include <thrust/system/cpp/execution_policy.h>
#endif

#include "device.h"
#include "hd.h"
#include "kernel_times.h"
#include "stage_marks.h"

namespace sphray::cpu_backend {

constexpr Backend kBackend = Backend::Cpu;

template <class T>
using Vector = std::vector<T>;

template <class T>
T* raw(Vector<T>& v) { return v.data(); }
template <class T>
const T* raw(const Vector<T>& v) { return v.data(); }

// Threads the device keeps in flight at once (layout choices of the field splats).
inline uint32_t resident_threads() { return 1; }

inline auto policy() {
#if defined(_OPENMP)
  return thrust::omp::par;
#else
  return thrust::cpp::par;
#endif
}

// Stable sort of keys[0, n) with their values (end_bit: the bits the keys use,
// which CUB's radix sort of the CUDA backend limits itself to).
inline void sort_pairs(Vector<uint32_t>& keys, Vector<uint32_t>& values, uint32_t n, int /*end_bit*/) {
  thrust::stable_sort_by_key(policy(), keys.begin(), keys.begin() + n, values.begin());
}

// The wall time between construction and stop(), as `name`'s
// (kernel_times.h), while kernel timing is on.
class LaunchTimer {
 public:
  explicit LaunchTimer(const char* name) : name_(name), timed_(kernel_timing()) {
    if (timed_) t0_ = std::chrono::steady_clock::now();
  }
  void stop() {
    if (timed_)
      add_kernel_time(name_, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count());
  }

 private:
  const char* name_;
  bool timed_;
  std::chrono::steady_clock::time_point t0_{};
};

// f(i) for i in [0, n) on all cores; `name` labels its time while kernel
// timing is on (kernel_times.h).
template <class F>
void parallel_for(const char* name, uint32_t n, const F& f) {
  LaunchTimer timer(name);
#pragma omp parallel for schedule(static)
  for (int64_t i = 0; i < int64_t(n); ++i) f(uint32_t(i));
  timer.stop();
}

// The CUDA backend's stream beside the default one; here the work runs in
// order, where it is queued.
class SideStream {
 public:
  void fork() {}
  void join() {}
  template <class F>
  void parallel_for(const char* name, uint32_t n, const F& f) {
    cpu_backend::parallel_for(name, n, f);
  }
  void* stream() const { return nullptr; }
};

// parallel_for on `side` where given, else on the default stream (in order either way).
template <class F>
void launch_on(SideStream*, const char* name, uint32_t n, const F& f) {
  parallel_for(name, n, f);
}

// *out = op-reduction of f(0), ..., f(n - 1) and init (the CUDA backend's
// leaves it on the device).
template <class T, class F, class Op>
void transform_reduce_into(uint32_t n, const F& f, const Op& op, const T& init, T* out) {
  *out = thrust::transform_reduce(policy(), thrust::counting_iterator<uint32_t>(0), thrust::counting_iterator<uint32_t>(n),
                                  f, init, op);
}

// The indices [0, n) split by their class cls(i), 0, 1 or 2: class 0 into
// first and class 1 into second, each in index order, class 2 into rest;
// counts[0], counts[1] and *rest_count their numbers (the CUDA backend's
// leaves them on the device and may order the rest otherwise).
template <class Cls>
void partition_three(const char* name, uint32_t n, const Cls& cls, uint32_t* first, uint32_t* second, uint32_t* rest,
                     uint32_t* counts, uint32_t* rest_count) {
  LaunchTimer timer(name);
  uint32_t* out[3] = {first, second, rest};
  uint32_t c[3] = {0, 0, 0};
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t k = std::min(uint32_t(cls(i)), 2u);
    out[k][c[k]++] = i;
  }
  counts[0] = c[0];
  counts[1] = c[1];
  *rest_count = c[2];
  timer.stop();
}

// The CUDA backend's read-back of a device value; here a copy.
template <class T>
class ReadBack {
 public:
  void start(const T* value) { value_ = *value; }
  const T& value() const { return value_; }
  const T& wait() const { return value_; }

 private:
  T value_{};
};

// The CUDA backend's copies that the run does not wait for; here copies.
class AsyncDownload {
 public:
  void begin() {}
  template <class T>
  void copy(const Vector<T>& src, size_t n, Vector<T>&, T* host) {
    thrust::copy(src.begin(), src.begin() + n, host);
  }
  std::function<void()> done() { return {}; }
};

template <class T>
void upload(Vector<T>& dst, const std::vector<T>& src) { dst.assign(src.begin(), src.end()); }

template <class T>
std::vector<T> download(const Vector<T>& v, size_t n) { return std::vector<T>(v.begin(), v.begin() + n); }

template <class T>
T read_one(const Vector<T>& v, size_t i) { return v[i]; }

// The wall time of a step's named stages (the CPU backend is synchronous):
// start(), end_of(stage) after each; ms(stage) is that stage's time.
class StageClock {
 public:
  void start() {
    marks_.clear();
    record("");
  }
  void end_of(const char* stage) { record(stage); }
  void finish() {}
  double ms(const char* stage) const {
    const int k = marks_.end_of(stage);
    return std::chrono::duration<double, std::milli>(t_[k] - t_[k - 1]).count();
  }

 private:
  void record(const char* stage) { t_[marks_.add(stage)] = std::chrono::steady_clock::now(); }
  StageMarks marks_;
  std::chrono::steady_clock::time_point t_[StageMarks::kMax];
};

}  // namespace sphray::cpu_backend
