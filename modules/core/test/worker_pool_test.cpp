#include "mosaicloc/core/worker_pool.hpp"

#include <atomic>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace mosaicloc::core {
namespace {

// Every index runs once, each on the worker its residue names, and run after run on the same
// threads: none is started per job.
TEST(WorkerPool, RunsEveryIndexOnceOnTheSameThreadsEveryTime) {
  WorkerPool pool(3);
  EXPECT_EQ(pool.threads(), 3);
  std::set<std::thread::id> all_threads;
  for (int run = 0; run < 200; ++run) {
    const std::size_t count = static_cast<std::size_t>(run % 17);
    std::vector<int> calls(count, 0);
    std::vector<std::thread::id> by(count);
    pool.Run(count, [&](std::size_t i) {
      ++calls[i];
      by[i] = std::this_thread::get_id();
    });
    for (std::size_t i = 0; i < count; ++i) {
      EXPECT_EQ(calls[i], 1) << "run " << run << " index " << i;
      EXPECT_NE(by[i], std::this_thread::get_id());
      if (i >= 3) {
        EXPECT_EQ(by[i], by[i - 3]);
      } else if (i >= 1) {
        EXPECT_NE(by[i], by[i - 1]);
      }
      all_threads.insert(by[i]);
    }
  }
  EXPECT_EQ(all_threads.size(), 3U);
}

TEST(WorkerPool, AThrowingCallIsRethrownAfterTheOthersRan) {
  WorkerPool pool(2);
  std::atomic<int> ran{0};
  EXPECT_THROW(pool.Run(10,
                        [&](std::size_t i) {
                          ++ran;
                          if (i == 3) throw std::runtime_error("index 3");
                        }),
               std::runtime_error);
  EXPECT_EQ(ran.load(), 10);
  // Still usable, and the error does not come back.
  std::atomic<int> again{0};
  pool.Run(4, [&](std::size_t) { ++again; });
  EXPECT_EQ(again.load(), 4);
}

TEST(WorkerPool, AtLeastOneThread) {
  WorkerPool pool(0);
  EXPECT_EQ(pool.threads(), 1);
  int sum = 0;
  pool.Run(5, [&](std::size_t i) { sum += static_cast<int>(i); });
  EXPECT_EQ(sum, 10);
}

}  // namespace
}  // namespace mosaicloc::core
