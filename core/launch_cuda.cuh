// CUDA backend: the per-element functors launched as named kernels, Thrust
// (CUB radix sort underneath) for sort, gather and reduce, CUDA events for
// stage and kernel timing. Every CUDA call is checked.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include <cuda_runtime.h>
#include <nvtx3/nvToolsExt.h>
#include <cub/device/device_partition.cuh>
#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_reduce.cuh>
#include <cub/util_allocator.cuh>
#include <thrust/count.h>
#include <thrust/device_vector.h>
#include <thrust/execution_policy.h>
#include <thrust/fill.h>
#include <thrust/binary_search.h>
#include <thrust/gather.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/iterator/transform_output_iterator.h>
#include <thrust/transform_scan.h>
#include <thrust/reduce.h>
#include <thrust/sequence.h>
#include <thrust/sort.h>
#include <thrust/transform_reduce.h>

#include "device.h"
#include "hd.h"
#include "kernel_times.h"
#include "stage_marks.h"

#define SPHRAY_CUDA_CHECK(expr)                                                                         \
  do {                                                                                                  \
    cudaError_t sphray_err_ = (expr);                                                                   \
    if (sphray_err_ != cudaSuccess)                                                                     \
      throw std::runtime_error(std::string(__FILE__) + ":" + std::to_string(__LINE__) + ": " #expr ": " + \
                               cudaGetErrorString(sphray_err_));                                        \
  } while (0)

namespace sphray::cuda_backend {

constexpr Backend kBackend = Backend::Cuda;

template <class T>
using Vector = thrust::device_vector<T>;

template <class T>
T* raw(Vector<T>& v) { return thrust::raw_pointer_cast(v.data()); }
template <class T>
const T* raw(const Vector<T>& v) { return thrust::raw_pointer_cast(v.data()); }

// Thrust's algorithms allocate temporary storage on every call; a cudaMalloc
// per sort or reduce costs more than the sort itself at a million particles.
// CUB's caching allocator keeps those blocks for reuse.
struct CachedTempAllocator {
  using value_type = char;
  static cub::CachingDeviceAllocator& cache() {
    static cub::CachingDeviceAllocator c(8, 3, 10, size_t(4) << 30);  // bins 8^3 .. 8^10 bytes, keep <= 4 GiB
    return c;
  }
  char* allocate(std::ptrdiff_t bytes) {
    void* p = nullptr;
    SPHRAY_CUDA_CHECK(cache().DeviceAllocate(&p, size_t(bytes)));
    return static_cast<char*>(p);
  }
  void deallocate(char* p, size_t) { SPHRAY_CUDA_CHECK(cache().DeviceFree(p)); }
};

// Threads the device keeps in flight at once (layout choices of the field splats).
inline uint32_t resident_threads() {
  static const uint32_t n = [] {
    int dev = 0, sms = 0, per_sm = 0;
    SPHRAY_CUDA_CHECK(cudaGetDevice(&dev));
    SPHRAY_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, dev));
    SPHRAY_CUDA_CHECK(cudaDeviceGetAttribute(&per_sm, cudaDevAttrMaxThreadsPerMultiProcessor, dev));
    return uint32_t(sms) * uint32_t(per_sm);
  }();
  return n;
}

// Thrust's algorithms on the default stream without waiting for them: with
// `par` each one (the grid sort's sequence and table, a scan) ended in a
// device synchronisation, and at 125k particles the GPU idled at each while
// the host launched the next kernels. Those that return a value to the host
// (reduce, count) still wait; the caching allocator hands a freed block to
// later work on the same stream only.
inline auto policy() {
  static CachedTempAllocator alloc;
  return thrust::cuda::par_nosync(alloc);
}

// Stable sort of keys[0, n) with their values by the key bits [0, end_bit):
// CUB's radix sort over only the bits the keys use (Thrust's sort_by_key sorts
// all 32, one pass per 8 bits), its double buffers from the caching allocator.
inline void sort_pairs(Vector<uint32_t>& keys, Vector<uint32_t>& values, uint32_t n, int end_bit) {
  if (n == 0) return;
  auto& cache = CachedTempAllocator::cache();
  void* alt = nullptr;
  SPHRAY_CUDA_CHECK(cache.DeviceAllocate(&alt, 2 * sizeof(uint32_t) * size_t(n)));
  uint32_t* keys_alt = static_cast<uint32_t*>(alt);
  cub::DoubleBuffer<uint32_t> k(raw(keys), keys_alt),
      v(raw(values), keys_alt + n);
  size_t bytes = 0;
  SPHRAY_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(nullptr, bytes, k, v, n, 0, end_bit));
  void* temp = nullptr;
  SPHRAY_CUDA_CHECK(cache.DeviceAllocate(&temp, bytes));
  SPHRAY_CUDA_CHECK(cub::DeviceRadixSort::SortPairs(temp, bytes, k, v, n, 0, end_bit));
  if (k.Current() != raw(keys))
    SPHRAY_CUDA_CHECK(cudaMemcpyAsync(raw(keys), k.Current(), sizeof(uint32_t) * n, cudaMemcpyDeviceToDevice));
  if (v.Current() != raw(values))
    SPHRAY_CUDA_CHECK(cudaMemcpyAsync(raw(values), v.Current(), sizeof(uint32_t) * n, cudaMemcpyDeviceToDevice));
  SPHRAY_CUDA_CHECK(cache.DeviceFree(temp));
  SPHRAY_CUDA_CHECK(cache.DeviceFree(alt));
}

template <class F>
__global__ void for_each_index_kernel(uint32_t n, F f) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) f(i);
}

// A functor may name its own register cap (static constexpr int
// kMaxRegisters) where the file-wide -maxrregcount (CMakeLists.txt) would
// make it spill: __maxnreg__ takes precedence for that kernel.
template <class F, int MaxRegisters>
__global__ __maxnreg__(MaxRegisters) void for_each_index_kernel_capped(uint32_t n, F f) {
  const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) f(i);
}

template <class F, class = void>
struct KernelRegisterCap { static constexpr int value = 0; };
template <class F>
struct KernelRegisterCap<F, std::void_t<decltype(F::kMaxRegisters)>> { static constexpr int value = F::kMaxRegisters; };

// The launches timed while kernel timing is on (kernel_times.h): their
// events, read once the device has passed them.
struct TimedLaunch {
  const char* name;
  cudaEvent_t start, stop;
};
inline std::vector<TimedLaunch>& timed_launches() {
  static std::vector<TimedLaunch> v;
  return v;
}
inline void resolve_timed_launches() {
  for (const TimedLaunch& l : timed_launches()) {
    SPHRAY_CUDA_CHECK(cudaEventSynchronize(l.stop));
    float ms = 0;
    SPHRAY_CUDA_CHECK(cudaEventElapsedTime(&ms, l.start, l.stop));
    add_kernel_time(l.name, ms);
    cudaEventDestroy(l.start);
    cudaEventDestroy(l.stop);
  }
  timed_launches().clear();
}

// The device time of the work queued on `stream` between start() and
// stop(), as `name`'s (kernel_times.h), while kernel timing is on.
class LaunchTimer {
 public:
  LaunchTimer(const char* name, cudaStream_t stream) : t_{name, nullptr, nullptr}, stream_(stream) {
    if (!kernel_timing()) return;
    SPHRAY_CUDA_CHECK(cudaEventCreate(&t_.start));
    SPHRAY_CUDA_CHECK(cudaEventCreate(&t_.stop));
    SPHRAY_CUDA_CHECK(cudaEventRecord(t_.start, stream_));
  }
  void stop() {
    if (!t_.start) return;
    SPHRAY_CUDA_CHECK(cudaEventRecord(t_.stop, stream_));
    timed_launches().push_back(t_);
    set_pending_kernel_times(&resolve_timed_launches);
  }

 private:
  TimedLaunch t_;
  cudaStream_t stream_;
};

// f(i) for i in [0, n) as one kernel on `stream`, named for the profiler (an
// NVTX range) and for the per-kernel times (kernel_times.h). `name` must
// outlive the process's last take_kernel_times() (a string literal).
template <class F>
void parallel_for_on(cudaStream_t stream, const char* name, uint32_t n, const F& f) {
  if (n == 0) return;
  nvtxRangePushA(name);
  LaunchTimer timer(name, stream);
  const uint32_t blocks = (n + kThreadsPerBlock - 1) / kThreadsPerBlock;
  if constexpr (KernelRegisterCap<F>::value > 0)
    for_each_index_kernel_capped<F, KernelRegisterCap<F>::value><<<blocks, kThreadsPerBlock, 0, stream>>>(n, f);
  else
    for_each_index_kernel<<<blocks, kThreadsPerBlock, 0, stream>>>(n, f);
  SPHRAY_CUDA_CHECK(cudaGetLastError());
  timer.stop();
  nvtxRangePop();
#if !defined(NDEBUG)
  SPHRAY_CUDA_CHECK(cudaDeviceSynchronize());
#endif
}

// The same on the default stream, where the solvers' work runs.
template <class F>
void parallel_for(const char* name, uint32_t n, const F& f) {
  parallel_for_on(0, name, n, f);
}

// A stream beside the default one, for work that runs alongside the
// solvers' (a decomposed run's ghost refresh and the small launches of a
// pass's other particle groups, flow_solver.inl): fork() orders what is
// queued on it next after everything queued on the default stream so far;
// join() orders what the default stream gets next after everything queued on
// it so far. Non-blocking, so that the legacy default stream does not
// serialise with it, and of the highest priority: its blocks are scheduled
// ahead of the default stream's, so that the short work that others wait for
// (the values sent to the peers) is not queued behind a full-size launch.
class SideStream {
 public:
  SideStream() {
    int least = 0, greatest = 0;
    SPHRAY_CUDA_CHECK(cudaDeviceGetStreamPriorityRange(&least, &greatest));
    SPHRAY_CUDA_CHECK(cudaStreamCreateWithPriority(&stream_, cudaStreamNonBlocking, greatest));
    SPHRAY_CUDA_CHECK(cudaEventCreateWithFlags(&forked_, cudaEventDisableTiming));
    SPHRAY_CUDA_CHECK(cudaEventCreateWithFlags(&done_, cudaEventDisableTiming));
  }
  ~SideStream() {
    cudaStreamSynchronize(stream_);
    cudaEventDestroy(done_);
    cudaEventDestroy(forked_);
    cudaStreamDestroy(stream_);
  }
  SideStream(const SideStream&) = delete;
  SideStream& operator=(const SideStream&) = delete;
  void fork() {
    SPHRAY_CUDA_CHECK(cudaEventRecord(forked_, cudaStreamLegacy));
    SPHRAY_CUDA_CHECK(cudaStreamWaitEvent(stream_, forked_, 0));
  }
  void join() {
    SPHRAY_CUDA_CHECK(cudaEventRecord(done_, stream_));
    SPHRAY_CUDA_CHECK(cudaStreamWaitEvent(cudaStreamLegacy, done_, 0));
  }
  template <class F>
  void parallel_for(const char* name, uint32_t n, const F& f) {
    parallel_for_on(stream_, name, n, f);
  }
  void* stream() const { return stream_; }

 private:
  cudaStream_t stream_{};
  cudaEvent_t forked_{}, done_{};
};

// parallel_for on `side` where given, else on the default stream.
template <class F>
void launch_on(SideStream* side, const char* name, uint32_t n, const F& f) {
  if (side) side->parallel_for(name, n, f);
  else parallel_for(name, n, f);
}

template <class T>
struct StoreValue {
  T* out;
  T value;
  __device__ void operator()(uint32_t) const { *out = value; }
};

// *out = op-reduction of f(0), ..., f(n - 1) and init, left on the device
// (CUB's reduce; Thrust's transform_reduce would copy the result to the host
// and wait for it).
template <class T, class F, class Op>
void transform_reduce_into(uint32_t n, const F& f, const Op& op, const T& init, T* out) {
  if (n == 0) {
    parallel_for("store_value", 1, StoreValue<T>{out, init});
    return;
  }
  const auto in = thrust::make_transform_iterator(thrust::counting_iterator<uint32_t>(0), f);
  auto& cache = CachedTempAllocator::cache();
  size_t bytes = 0;
  SPHRAY_CUDA_CHECK(cub::DeviceReduce::Reduce(nullptr, bytes, in, out, n, op, init));
  void* temp = nullptr;
  SPHRAY_CUDA_CHECK(cache.DeviceAllocate(&temp, bytes));
  SPHRAY_CUDA_CHECK(cub::DeviceReduce::Reduce(temp, bytes, in, out, n, op, init));
  SPHRAY_CUDA_CHECK(cache.DeviceFree(temp));
}

// The indices [0, n) split by their class cls(i), 0, 1 or 2 (n < 2^30):
// class 0 into first and class 1 into second, each in index order, class 2
// into rest in any order; counts[0] and counts[1] their numbers and
// *rest_count the rest's, left on the device. One pass of CUB's three-way
// partition over i << 2 | cls(i), so each class is computed once, timed as
// `name` while kernel timing is on.
template <class Cls>
struct PackClass {
  Cls cls;
  __device__ uint32_t operator()(uint32_t i) const { return i << 2 | uint32_t(cls(i)); }
};
struct IsClass {
  uint32_t c;
  __device__ bool operator()(uint32_t v) const { return (v & 3u) == c; }
};
struct UnpackIndex {
  __device__ uint32_t operator()(uint32_t v) const { return v >> 2; }
};
struct RestCount {
  const uint32_t* counts;
  uint32_t* rest;
  uint32_t n;
  __device__ void operator()(uint32_t) const { *rest = n - counts[0] - counts[1]; }
};
template <class Cls>
void partition_three(const char* name, uint32_t n, const Cls& cls, uint32_t* first, uint32_t* second, uint32_t* rest,
                     uint32_t* counts, uint32_t* rest_count) {
  if (n >= (1u << 30)) throw std::invalid_argument("partition_three: more than 2^30 items");
  LaunchTimer timer(name, 0);
  const auto in = thrust::make_transform_iterator(thrust::counting_iterator<uint32_t>(0), PackClass<Cls>{cls});
  const auto out0 = thrust::make_transform_output_iterator(first, UnpackIndex{});
  const auto out1 = thrust::make_transform_output_iterator(second, UnpackIndex{});
  const auto out2 = thrust::make_transform_output_iterator(rest, UnpackIndex{});
  auto& cache = CachedTempAllocator::cache();
  size_t bytes = 0;
  SPHRAY_CUDA_CHECK(cub::DevicePartition::If(nullptr, bytes, in, out0, out1, out2, counts, int(n), IsClass{0},
                                             IsClass{1}));
  void* temp = nullptr;
  SPHRAY_CUDA_CHECK(cache.DeviceAllocate(&temp, bytes));
  SPHRAY_CUDA_CHECK(cub::DevicePartition::If(temp, bytes, in, out0, out1, out2, counts, int(n), IsClass{0},
                                             IsClass{1}));
  SPHRAY_CUDA_CHECK(cache.DeviceFree(temp));
  for_each_index_kernel<<<1, 1>>>(1u, RestCount{counts, rest_count, n});
  SPHRAY_CUDA_CHECK(cudaGetLastError());
  timer.stop();
}

// A value on the device that the host reads without a wait of its own:
// start() queues its copy into pinned memory behind the work before it;
// value() is valid once the host has waited for something queued after
// start() (the solver's stage clock at the end of a step); wait() waits for
// the copy alone, while the work queued after it goes on.
template <class T>
class ReadBack {
 public:
  ReadBack() {
    SPHRAY_CUDA_CHECK(cudaMallocHost(&host_, sizeof(T)));
    SPHRAY_CUDA_CHECK(cudaEventCreateWithFlags(&copied_, cudaEventDisableTiming));
  }
  ~ReadBack() {
    cudaEventDestroy(copied_);
    cudaFreeHost(host_);
  }
  ReadBack(const ReadBack&) = delete;
  ReadBack& operator=(const ReadBack&) = delete;
  void start(const T* device_value) {
    SPHRAY_CUDA_CHECK(cudaMemcpyAsync(host_, device_value, sizeof(T), cudaMemcpyDeviceToHost));
    SPHRAY_CUDA_CHECK(cudaEventRecord(copied_));
  }
  const T& value() const { return *host_; }
  const T& wait() const {
    SPHRAY_CUDA_CHECK(cudaEventSynchronize(copied_));
    return *host_;
  }

 private:
  T* host_ = nullptr;
  cudaEvent_t copied_ = nullptr;
};

// Copies off the device that the run does not wait for (the export's
// snapshots): each array is copied on the device into a staging buffer, in
// order with the step's work, and from there into host memory on a stream of
// its own while the next steps run. done() gives what waits for the copies;
// the next begin() waits for them before the staging buffers are reused.
class AsyncDownload {
 public:
  AsyncDownload() {
    SPHRAY_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
    SPHRAY_CUDA_CHECK(cudaEventCreateWithFlags(&staged_, cudaEventDisableTiming));
  }
  ~AsyncDownload() {
    if (last_) cudaEventSynchronize(*last_);
    cudaEventDestroy(staged_);
    cudaStreamDestroy(stream_);
  }
  AsyncDownload(const AsyncDownload&) = delete;
  AsyncDownload& operator=(const AsyncDownload&) = delete;

  void begin() {
    if (last_) SPHRAY_CUDA_CHECK(cudaEventSynchronize(*last_));
  }
  template <class T>
  void copy(const Vector<T>& src, size_t n, Vector<T>& staging, T* host) {
    if (staging.size() < n) staging.resize(n);
    const size_t bytes = n * sizeof(T);
    SPHRAY_CUDA_CHECK(cudaMemcpyAsync(thrust::raw_pointer_cast(staging.data()), thrust::raw_pointer_cast(src.data()),
                                      bytes, cudaMemcpyDeviceToDevice, cudaStreamLegacy));
    SPHRAY_CUDA_CHECK(cudaEventRecord(staged_, cudaStreamLegacy));
    SPHRAY_CUDA_CHECK(cudaStreamWaitEvent(stream_, staged_, 0));
    SPHRAY_CUDA_CHECK(cudaMemcpyAsync(host, thrust::raw_pointer_cast(staging.data()), bytes, cudaMemcpyDeviceToHost,
                                      stream_));
  }
  std::function<void()> done() {
    cudaEvent_t e;
    SPHRAY_CUDA_CHECK(cudaEventCreateWithFlags(&e, cudaEventDisableTiming));
    SPHRAY_CUDA_CHECK(cudaEventRecord(e, stream_));
    last_ = std::shared_ptr<cudaEvent_t>(new cudaEvent_t(e), [](cudaEvent_t* p) {
      cudaEventDestroy(*p);
      delete p;
    });
    return [ev = last_] { SPHRAY_CUDA_CHECK(cudaEventSynchronize(*ev)); };
  }

 private:
  cudaStream_t stream_{};
  cudaEvent_t staged_{};
  std::shared_ptr<cudaEvent_t> last_;
};

template <class T>
void upload(Vector<T>& dst, const std::vector<T>& src) { dst.assign(src.begin(), src.end()); }

template <class T>
std::vector<T> download(const Vector<T>& v, size_t n) {
  std::vector<T> out(n);
  if (n) thrust::copy(v.begin(), v.begin() + n, out.begin());
  return out;
}

template <class T>
T read_one(const Vector<T>& v, size_t i) { return v[i]; }

// The device time of a step's named stages: start(), end_of(stage) after
// each, finish() waits for the last; ms(stage) is then that stage's time
// (CUDA events).
class StageClock {
 public:
  StageClock() { for (auto& e : ev_) SPHRAY_CUDA_CHECK(cudaEventCreate(&e)); }
  ~StageClock() { for (auto& e : ev_) cudaEventDestroy(e); }
  StageClock(const StageClock&) = delete;
  StageClock& operator=(const StageClock&) = delete;
  void start() {
    marks_.clear();
    record("");
  }
  void end_of(const char* stage) { record(stage); }
  void finish() { SPHRAY_CUDA_CHECK(cudaEventSynchronize(ev_[marks_.last()])); }
  double ms(const char* stage) const {
    const int k = marks_.end_of(stage);
    float out = 0;
    SPHRAY_CUDA_CHECK(cudaEventElapsedTime(&out, ev_[k - 1], ev_[k]));
    return out;
  }

 private:
  void record(const char* stage) { SPHRAY_CUDA_CHECK(cudaEventRecord(ev_[marks_.add(stage)])); }
  StageMarks marks_;
  cudaEvent_t ev_[StageMarks::kMax];
};

}  // namespace sphray::cuda_backend
