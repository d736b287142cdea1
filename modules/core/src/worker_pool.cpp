#include "mosaicloc/core/worker_pool.hpp"

#include <algorithm>
#include <utility>

namespace mosaicloc::core {

WorkerPool::WorkerPool(int threads) {
  const auto n = static_cast<std::size_t>(std::max(1, threads));
  workers_.reserve(n);
  for (std::size_t w = 0; w < n; ++w) workers_.emplace_back([this, w] { Work(w); });
}

WorkerPool::~WorkerPool() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  start_.notify_all();
  for (std::thread& worker : workers_) worker.join();
}

void WorkerPool::Run(std::size_t count, const std::function<void(std::size_t)>& job) {
  std::unique_lock lock(mutex_);
  job_ = &job;
  count_ = count;
  error_ = nullptr;
  running_ = workers_.size();
  ++generation_;
  start_.notify_all();
  done_.wait(lock, [this] { return running_ == 0; });
  job_ = nullptr;
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

void WorkerPool::Work(std::size_t worker) {
  std::size_t seen = 0;
  for (;;) {
    std::unique_lock lock(mutex_);
    start_.wait(lock, [&] { return stopping_ || generation_ != seen; });
    if (stopping_) return;
    seen = generation_;
    const std::function<void(std::size_t)>& job = *job_;
    const std::size_t count = count_;
    const std::size_t stride = workers_.size();
    lock.unlock();
    std::exception_ptr error;
    for (std::size_t i = worker; i < count; i += stride) {
      try {
        job(i);
      } catch (...) {
        if (!error) error = std::current_exception();
      }
    }
    lock.lock();
    if (error && !error_) error_ = error;
    if (--running_ == 0) done_.notify_one();
  }
}

}  // namespace mosaicloc::core
