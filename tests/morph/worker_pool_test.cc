#include "morph/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

namespace vb::morph {
namespace {

TEST(WorkerPoolTest, CallsEveryIndexOnceOnAsManyThreadsAsAsked) {
  for (int threads : {1, 2, 3}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (int n : {0, 1, 2, 7, 100}) {
      std::vector<std::atomic<int>> calls(static_cast<std::size_t>(n));
      std::mutex mutex;
      std::set<std::thread::id> ids;
      pool.ForEach(n, [&](int i) {
        ++calls[static_cast<std::size_t>(i)];
        // Long enough that every thread gets an index before they run out.
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        const std::lock_guard<std::mutex> lock(mutex);
        ids.insert(std::this_thread::get_id());
      });
      for (int i = 0; i < n; ++i) EXPECT_EQ(calls[static_cast<std::size_t>(i)], 1) << i;
      if (n == 0) continue;
      EXPECT_EQ(static_cast<int>(ids.size()), std::min(n, threads))
          << threads << " threads, " << n << " calls";
      if (threads == 1) {
        EXPECT_EQ(*ids.begin(), std::this_thread::get_id());
      }
    }
  }
}

TEST(WorkerPoolTest, ClampsTheThreadCount) {
  EXPECT_EQ(WorkerPool(0).threads(), 1);
  EXPECT_EQ(WorkerPool(-3).threads(), 1);
  EXPECT_EQ(WorkerPool(1000).threads(), WorkerPool::kMaxThreads);
}

TEST(WorkerPoolTest, RethrowsABodysExceptionAfterTheOthersFinish) {
  WorkerPool pool(2);
  std::atomic<int> finished{0};
  EXPECT_THROW(pool.ForEach(10,
                            [&](int i) {
                              if (i == 3) throw std::runtime_error("index 3");
                              std::this_thread::sleep_for(std::chrono::milliseconds(1));
                              ++finished;
                            }),
               std::runtime_error);
  EXPECT_EQ(finished, 9);
  // The pool still works afterwards.
  std::atomic<int> sum{0};
  pool.ForEach(4, [&](int i) { sum += i; });
  EXPECT_EQ(sum, 6);
}

TEST(WorkerPoolTest, RunsEachWorkerInsideTheWrapper) {
  std::atomic<int> wrapped{0};
  thread_local bool inside = false;
  {
    WorkerPool pool(3, [&](const std::function<void()>& body) {
      inside = true;
      ++wrapped;
      body();
    });
    std::atomic<int> outside_calls{0};
    std::mutex mutex;
    std::set<std::thread::id> workers;
    pool.ForEach(30, [&](int) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      if (!inside) ++outside_calls;
      const std::lock_guard<std::mutex> lock(mutex);
      if (inside) workers.insert(std::this_thread::get_id());
    });
    EXPECT_EQ(wrapped, 2);  // two workers; the caller is not wrapped
    EXPECT_EQ(workers.size(), 2u);
    EXPECT_GT(outside_calls, 0);  // the caller took part
  }
}

}  // namespace
}  // namespace vb::morph
