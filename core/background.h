// One background thread that runs jobs in order, with one job queued behind
// the one running (double buffering): the producer (the simulation) waits only
// when it is two jobs ahead. The first failed job stops the queue; its message
// is kept for the owner to report with its own error type. Used by the HDF5
// frame writer and the PNG frame writer.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

namespace sphray {

// A file that a run writes as it goes (PNG frames, metrics CSV, summary JSON)
// could not be written after the run began, e.g. a full disk: the run stops
// (exit 1, as for the HDF5 export). A path that cannot be written at all is
// found before the run and is bad input (exit 2).
struct OutputError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class BackgroundQueue {
 public:
  // `thread_init` runs first on the new thread (per-thread library settings).
  explicit BackgroundQueue(std::function<void()> thread_init = nullptr);
  ~BackgroundQueue();  // runs what is queued and joins; a failure is reported by finish()
  BackgroundQueue(const BackgroundQueue&) = delete;
  BackgroundQueue& operator=(const BackgroundQueue&) = delete;

  // Queues a job; blocks while another is still queued. false (and the job
  // dropped): an earlier job failed, see error().
  bool submit(std::function<void()> job);
  // Runs what is queued and joins the thread. false: a job failed.
  bool finish();
  bool failed() const;
  std::string error() const;
  size_t done() const;                                 // jobs that completed
  double seconds_waited() const { return waited_; }    // time submit() blocked (the producer's thread)

 private:
  void loop(const std::function<void()>& thread_init);

  std::function<void()> pending_;
  bool stop_ = false;
  std::string error_;
  size_t done_ = 0;
  double waited_ = 0;
  mutable std::mutex m_;
  std::condition_variable cv_;
  std::thread thread_;
};

}  // namespace sphray
