#include "morph/worker_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

namespace vb::morph {
namespace {

// Holds the first `count` calls until all of them have arrived (or 10 s have passed), so
// that each is on a thread of its own however the threads are scheduled: a thread held here
// cannot take another index.
class Rendezvous {
 public:
  explicit Rendezvous(int count) : count_(count) {}
  void Arrive() {
    std::unique_lock<std::mutex> lock(mutex_);
    if (arrived_ >= count_) return;
    ++arrived_;
    all_.notify_all();
    all_.wait_for(lock, std::chrono::seconds(10), [&] { return arrived_ >= count_; });
  }

 private:
  const int count_;
  int arrived_ = 0;
  std::mutex mutex_;
  std::condition_variable all_;
};

TEST(WorkerPoolTest, CallsEveryIndexOnceOnAsManyThreadsAsAsked) {
  for (int threads : {1, 2, 3}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (int n : {0, 1, 2, 7, 100}) {
      std::vector<std::atomic<int>> calls(static_cast<std::size_t>(n));
      std::mutex mutex;
      std::set<std::thread::id> ids;
      Rendezvous first(std::min(n, threads));
      pool.ForEach(n, [&](int i) {
        ++calls[static_cast<std::size_t>(i)];
        {
          const std::lock_guard<std::mutex> lock(mutex);
          ids.insert(std::this_thread::get_id());
        }
        first.Arrive();
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

// Blocks cover [0, n) once each, the last one shorter, with or without a pool.
TEST(WorkerPoolTest, BlocksCoverEveryIndexOnce) {
  WorkerPool pool(2);
  for (WorkerPool* p : {static_cast<WorkerPool*>(nullptr), &pool}) {
    for (std::int64_t n : {0, 1, 5, 8, 9, 100}) {
      std::vector<std::atomic<int>> calls(static_cast<std::size_t>(n));
      std::atomic<int> blocks = 0;
      ForEachBlock(p, n, 4, [&](std::int64_t first, std::int64_t last) {
        ++blocks;
        EXPECT_EQ(first % 4, 0);
        EXPECT_LE(last - first, 4);
        EXPECT_TRUE(last - first == 4 || last == n) << first << " " << last;
        for (std::int64_t i = first; i < last; ++i) ++calls[static_cast<std::size_t>(i)];
      });
      EXPECT_EQ(blocks, (n + 3) / 4) << n;
      for (std::int64_t i = 0; i < n; ++i) EXPECT_EQ(calls[static_cast<std::size_t>(i)], 1) << i;
    }
  }
}

TEST(WorkerPoolTest, ClampsTheThreadCount) {
  EXPECT_EQ(WorkerPool(0).threads(), 1);
  EXPECT_EQ(WorkerPool(-3).threads(), 1);
  EXPECT_EQ(WorkerPool(1000).threads(), WorkerPool::kMaxThreads);
}

TEST(WorkerPoolTest, RethrowsABodysExceptionAndStartsNothingAfterIt) {
  for (int threads : {1, 2}) {
    WorkerPool pool(threads);
    std::atomic<int> finished{0};
    EXPECT_THROW(pool.ForEach(10,
                              [&](int i) {
                                if (i == 3) throw std::runtime_error("index 3");
                                ++finished;
                              }),
                 std::runtime_error);
    // On one thread the indices run in order: 0, 1 and 2, then none. On two, which of the
    // others ran depends on the scheduling.
    if (threads == 1) {
      EXPECT_EQ(finished, 3);
    }
    // The pool still works afterwards.
    std::atomic<int> sum{0};
    pool.ForEach(4, [&](int i) { sum += i; });
    EXPECT_EQ(sum, 6);
  }
}

// A worker that waited for helpers would wait for itself: its nested loop runs on it alone.
TEST(WorkerPoolTest, ANestedLoopOnAWorkerRunsThereAlone) {
  WorkerPool pool(2);
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<int> calls{0};
  Rendezvous both(2);
  pool.ForEach(2, [&](int) {
    both.Arrive();  // each outer call on its own thread, the worker's included
    const std::thread::id outer = std::this_thread::get_id();
    pool.ForEach(3, [&](int) {
      if (outer != caller) {
        EXPECT_EQ(std::this_thread::get_id(), outer);
      }
      ++calls;
    });
  });
  EXPECT_EQ(calls, 6);
}

TEST(WorkerPoolTest, RunsEachWorkerInsideTheWrapper) {
  std::atomic<int> wrapped{0};
  thread_local bool inside = false;
  WorkerPool pool(3, [&](const std::function<void()>& body) {
    inside = true;
    ++wrapped;
    body();
  });
  std::mutex mutex;
  int caller_calls = 0;
  std::set<std::thread::id> workers;
  const std::thread::id caller = std::this_thread::get_id();
  Rendezvous all(3);
  pool.ForEach(30, [&](int) {
    {
      const std::lock_guard<std::mutex> lock(mutex);
      if (std::this_thread::get_id() == caller) {
        EXPECT_FALSE(inside);  // the caller is not wrapped
        ++caller_calls;
      } else {
        EXPECT_TRUE(inside) << "a worker outside the wrapper";
        workers.insert(std::this_thread::get_id());
      }
    }
    all.Arrive();
  });
  EXPECT_EQ(wrapped, 2);  // two workers
  EXPECT_EQ(workers.size(), 2u);
  EXPECT_GT(caller_calls, 0);
}

}  // namespace
}  // namespace vb::morph
