#pragma once

#include <condition_variable>
#include <cstddef>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace mosaicloc::core {

/// A fixed set of threads that runs the indices of one job at a time and waits for them. For
/// work cut into many small batches (frames rendered eight at a time): threads started per batch
/// cost their start-up, and every thread that ever ran one of OpenCV's parallel loops leaves
/// about a kilobyte of OpenCV's per-thread state behind, which adds up over a long drive.
class WorkerPool {
 public:
  /// Starts `threads` (at least 1) workers.
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()); }

  /// Calls job(i) for every i in [0, count): worker w takes w, w + threads, ... so which thread
  /// runs an index does not depend on timing. Returns when every index is done; if a call threw,
  /// the first exception is rethrown here (the other indices still ran). One Run at a time.
  void Run(std::size_t count, const std::function<void(std::size_t)>& job);

 private:
  void Work(std::size_t worker);

  std::mutex mutex_;
  std::condition_variable start_, done_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::size_t count_ = 0;
  std::size_t generation_ = 0;  ///< raised by every Run
  std::size_t running_ = 0;     ///< workers still on this generation's job
  std::exception_ptr error_;
  bool stopping_ = false;
  std::vector<std::thread> workers_;  // last: started once everything above exists
};

}  // namespace mosaicloc::core
