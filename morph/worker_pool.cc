#include "morph/worker_pool.h"

#define EIGEN_USE_THREADS
#include <algorithm>
#include <atomic>
#include <exception>
#include <limits>
#include <mutex>
#include <thread>
#include <unsupported/Eigen/CXX11/ThreadPool>
#include <utility>

#include "io/error.h"

namespace vb::morph {
namespace {

// Eigen's standard thread environment, with every thread's body run by the pool's wrapper.
struct WrappedEnvironment {
  using Task = Eigen::StlThreadEnvironment::Task;

  class EnvThread {
   public:
    explicit EnvThread(std::function<void()> f) : thread_(std::move(f)) {}
    ~EnvThread() { thread_.join(); }
    void OnCancel() {}

   private:
    std::thread thread_;
  };

  EnvThread* CreateThread(std::function<void()> f) {
    if (!wrapper) return new EnvThread(std::move(f));
    return new EnvThread([w = wrapper, f = std::move(f)] { w(f); });
  }
  Task CreateTask(std::function<void()> f) { return Task{std::move(f)}; }
  void ExecuteTask(const Task& t) { t.f(); }

  WorkerWrapper wrapper;
};

}  // namespace

struct WorkerPool::Pool {
  Pool(int workers, WorkerWrapper wrapper)
      : threads(workers, /*allow_spinning=*/false, WrappedEnvironment{std::move(wrapper)}) {}
  Eigen::ThreadPoolTempl<WrappedEnvironment> threads;
};

WorkerPool::WorkerPool(int threads, WorkerWrapper wrapper)
    : threads_(std::clamp(threads, 1, kMaxThreads)) {
  if (threads_ > 1) pool_ = std::make_unique<Pool>(threads_ - 1, std::move(wrapper));
}

WorkerPool::~WorkerPool() = default;

void WorkerPool::ForEach(int n, FunctionRef<void(int)> body) {
  if (n <= 0) return;
  // On one of this pool's workers (a nested loop) the helpers would queue behind the caller
  // itself: the loop runs here alone.
  const bool nested = pool_ && pool_->threads.CurrentThreadId() != -1;
  const int helpers = pool_ && !nested ? std::min(n, threads_) - 1 : 0;
  std::atomic<int> next{0};
  std::mutex error_mutex;
  std::exception_ptr error;
  // Each participant takes the next unclaimed index until none is left.
  const auto run = [&] {
    for (int i = next.fetch_add(1); i < n; i = next.fetch_add(1)) {
      try {
        body(i);
      } catch (...) {
        next.store(n);  // start nothing more
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    }
  };
  Eigen::Barrier done(static_cast<unsigned>(helpers));
  for (int h = 0; h < helpers; ++h) {
    pool_->threads.Schedule([&] {
      run();
      done.Notify();
    });
  }
  run();
  done.Wait();
  if (error) std::rethrow_exception(error);
}

void ForEach(WorkerPool* pool, int n, FunctionRef<void(int)> body) {
  if (pool != nullptr) {
    pool->ForEach(n, body);
  } else {
    for (int i = 0; i < n; ++i) body(i);
  }
}

void ForEachBlock(WorkerPool* pool, std::int64_t n, std::int64_t block,
                  FunctionRef<void(std::int64_t first, std::int64_t last)> body) {
  VB_DEMAND(block >= 1 && n >= 0 && (n + block - 1) / block <= std::numeric_limits<int>::max());
  const int blocks = static_cast<int>((n + block - 1) / block);
  ForEach(pool, blocks, [&](int b) {
    const std::int64_t first = static_cast<std::int64_t>(b) * block;
    body(first, std::min(n, first + block));
  });
}

}  // namespace vb::morph
