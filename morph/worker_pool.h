#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <type_traits>
#include <utility>

namespace vb::morph {

/// A reference to a callable, as C++26's std::function_ref: it neither owns nor copies what it
/// refers to, so passing a lambda to a loop below allocates nothing (a std::function holding
/// a lambda that captures more than two references allocates). It refers to function
/// objects (a lambda, a std::function), not to a plain function named as such. @pre the
/// callable outlives every call made through the reference: pass it down the stack, do not
/// store it (`FunctionRef<void(int)> f = [&](int) {...};` refers to a lambda already gone).
template <class Signature>
class FunctionRef;

template <class R, class... Args>
class FunctionRef<R(Args...)> {
 public:
  // Not a FunctionRef itself (that is the copy constructor), and callable as R(Args...).
  template <class F,
            class = std::enable_if_t<!std::is_same_v<std::remove_cvref_t<F>, FunctionRef> &&
                                     std::is_invocable_r_v<R, F&, Args...>>>
  FunctionRef(F&& f) noexcept  // NOLINT(google-explicit-constructor): a lambda converts
      : callable_(const_cast<void*>(static_cast<const void*>(std::addressof(f)))),
        call_([](void* callable, Args... args) -> R {
          auto& target = *static_cast<std::remove_reference_t<F>*>(callable);
          if constexpr (std::is_void_v<R>) {
            std::invoke(target, std::forward<Args>(args)...);  // a result, if any, is dropped
          } else {
            return std::invoke(target, std::forward<Args>(args)...);
          }
        }) {}

  R operator()(Args... args) const { return call_(callable_, std::forward<Args>(args)...); }

 private:
  void* callable_;
  R (*call_)(void*, Args...);
};

/// Runs a worker thread's whole life: sets the thread up, calls @p body exactly once (it
/// returns when the pool is destroyed) and tears down; it must not throw. The daemon gives
/// each worker its memory budget so.
using WorkerWrapper = std::function<void(const std::function<void()>& body)>;

/// A fixed set of threads, made once, that share loops with the thread calling ForEach (on
/// Eigen's ThreadPool, without spinning: idle workers sleep). A ForEach called from a body
/// running on one of the workers runs on that worker alone.
class WorkerPool {
 public:
  /// @param threads threads a loop runs on, the caller's included: 1 makes no worker and
  ///   runs every loop on the caller. Clamped to [1, kMaxThreads].
  /// @param wrapper runs each worker thread (none: the thread just runs).
  explicit WorkerPool(int threads = 1, WorkerWrapper wrapper = {});
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  static constexpr int kMaxThreads = 16;

  int threads() const { return threads_; }

  /// Calls body(i) once for every i in [0, n), on the caller and the workers, in no set
  /// order; returns when every call has. A body that writes only its own i's results gives
  /// the same results on any number of threads. Once a call throws, no further index is
  /// started; the first exception caught is rethrown here after the running calls finish.
  void ForEach(int n, FunctionRef<void(int)> body);

 private:
  struct Pool;
  int threads_ = 1;
  std::unique_ptr<Pool> pool_;
};

/// @p pool's ForEach, or the same loop on the caller alone when @p pool is null.
void ForEach(WorkerPool* pool, int n, FunctionRef<void(int)> body);

/// [0, @p n) cut into blocks of @p block (the last may be shorter), body(first, last) called
/// once per block as ForEach calls its body: for loops over many cheap items, each block
/// setting up its own scratch. @pre block >= 1.
void ForEachBlock(WorkerPool* pool, std::int64_t n, std::int64_t block,
                  FunctionRef<void(std::int64_t first, std::int64_t last)> body);

}  // namespace vb::morph
