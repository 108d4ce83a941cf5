#include "background.h"

#include <chrono>
#include <exception>

namespace sphray {

BackgroundQueue::BackgroundQueue(std::function<void()> thread_init)
    : thread_([this, init = std::move(thread_init)] { loop(init); }) {}

BackgroundQueue::~BackgroundQueue() { finish(); }

bool BackgroundQueue::submit(std::function<void()> job) {
  std::unique_lock<std::mutex> lock(m_);
  const auto t0 = std::chrono::steady_clock::now();
  cv_.wait(lock, [&] { return !pending_ || !error_.empty(); });
  waited_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (!error_.empty() || stop_) return false;
  pending_ = std::move(job);
  cv_.notify_all();
  return true;
}

bool BackgroundQueue::finish() {
  {
    std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
    cv_.notify_all();
  }
  if (thread_.joinable()) thread_.join();
  return !failed();
}

bool BackgroundQueue::failed() const {
  std::lock_guard<std::mutex> lock(m_);
  return !error_.empty();
}

std::string BackgroundQueue::error() const {
  std::lock_guard<std::mutex> lock(m_);
  return error_;
}

size_t BackgroundQueue::done() const {
  std::lock_guard<std::mutex> lock(m_);
  return done_;
}

void BackgroundQueue::loop(const std::function<void()>& thread_init) {
  if (thread_init) thread_init();
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> lock(m_);
      cv_.wait(lock, [&] { return bool(pending_) || stop_; });
      if (!pending_) return;  // stopped and drained
      job = std::move(pending_);
      pending_ = nullptr;
      cv_.notify_all();  // the producer may queue the next job while this one runs
    }
    std::string err;
    try {
      job();
    } catch (const std::exception& e) {
      err = e.what();
      if (err.empty()) err = "unknown error";
    } catch (...) {
      err = "unknown error";
    }
    std::lock_guard<std::mutex> lock(m_);
    if (!err.empty()) {
      error_ = err;
      pending_ = nullptr;  // nothing more runs after a failure
      cv_.notify_all();
      return;
    }
    ++done_;
    cv_.notify_all();
  }
}

}  // namespace sphray
