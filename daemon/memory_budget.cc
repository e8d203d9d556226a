#include "daemon/memory_budget.h"

#include <errno.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <new>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define VB_MEMORY_BUDGET 0
#else
#define VB_MEMORY_BUDGET 1
#include <mimalloc.h>
#endif

namespace vb::daemon {
namespace {

#if VB_MEMORY_BUDGET
// The arena's address range, set once by ReserveMemoryBudget.
std::atomic<std::uintptr_t> g_begin{0}, g_end{0};
std::atomic<int> g_arena_id{-1};

// Counters of one budget thread. Only that thread writes them (plain load and store, no
// locked instruction on the allocation path); GetMemoryBudgetStats reads them from anywhere.
// live counts bytes allocated minus bytes freed by this thread, so one thread's may go
// negative when it frees another's blocks; the sum over threads is the arena's content.
struct alignas(64) ThreadCounters {  // a cache line each: no false sharing
  std::atomic<long> arena{0}, heap{0};
  std::atomic<long long> live{0}, peak{0};
};
constexpr int kMaxBudgetThreads = 32;
ThreadCounters g_threads[kMaxBudgetThreads];
std::atomic<int> g_num_threads{0};
// Threads without a budget: several may write, so these are atomic additions.
std::atomic<long> g_other_allocations{0};
std::atomic<long long> g_other_live{0};
// g_other_live when the peak was last reset. Other threads allocate outside the arena, so
// in the arena they only free (their live only falls): this is their peak since the reset.
std::atomic<long long> g_other_live_at_reset{0};

// The calling thread's heap in the arena and its counters, or null when the thread has no
// budget. Trivially constructed thread_locals: reading them allocates nothing.
thread_local mi_heap_t* t_heap = nullptr;
thread_local ThreadCounters* t_counters = nullptr;

bool InArena(const void* p) {
  const auto a = reinterpret_cast<std::uintptr_t>(p);
  return a >= g_begin.load(std::memory_order_relaxed) && a < g_end.load(std::memory_order_relaxed);
}

void Bump(std::atomic<long>& counter) {
  counter.store(counter.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}

// Adds @p bytes (negative: freed) to the arena's content as this thread sees it.
void AddLive(long long bytes) {
  if (ThreadCounters* c = t_counters) {
    const long long live = c->live.load(std::memory_order_relaxed) + bytes;
    c->live.store(live, std::memory_order_relaxed);
    if (live > c->peak.load(std::memory_order_relaxed))
      c->peak.store(live, std::memory_order_relaxed);
  } else {
    g_other_live.fetch_add(bytes, std::memory_order_relaxed);
  }
}

// Counts a new block and where it landed. A thread with counters is a budget thread, so a
// block of its that is outside the arena came from the heap.
void* Account(void* p) {
  if (p == nullptr) return p;
  ThreadCounters* c = t_counters;
  if (InArena(p)) {
    if (c != nullptr) Bump(c->arena);
    AddLive(static_cast<long long>(mi_usable_size(p)));
  } else if (c != nullptr) {
    Bump(c->heap);
  } else {
    g_other_allocations.fetch_add(1, std::memory_order_relaxed);
  }
  return p;
}

void Release(void* p) {
  if (p != nullptr && InArena(p)) AddLive(-static_cast<long long>(mi_usable_size(p)));
}

// A budget thread's allocation: from its heap in the arena, or, should the arena be full,
// from its ordinary heap (counted by Account, never a failure). @p allocate(heap) makes it.
template <typename AllocateInHeap>
void* AllocateWithFallback(mi_heap_t* heap, AllocateInHeap allocate) {
  const int saved_errno = errno;
  void* p = allocate(heap);
  if (p == nullptr) p = allocate(mi_heap_get_backing());
  if (p != nullptr) errno = saved_errno;
  return Account(p);
}

// malloc (alignment 0) and its aligned relatives.
void* Allocate(std::size_t n, std::size_t alignment) {
  if (mi_heap_t* heap = t_heap)
    return AllocateWithFallback(heap, [&](mi_heap_t* h) {
      return alignment == 0 ? mi_heap_malloc(h, n) : mi_heap_malloc_aligned(h, n, alignment);
    });
  // mimalloc's own entry points, which also set up a new thread.
  return Account(alignment == 0 ? mi_malloc(n) : mi_malloc_aligned(n, alignment));
}

void* AllocateZeroed(std::size_t count, std::size_t size) {
  if (mi_heap_t* heap = t_heap)
    return AllocateWithFallback(heap, [&](mi_heap_t* h) { return mi_heap_calloc(h, count, size); });
  return Account(mi_calloc(count, size));
}

void* Reallocate(void* p, std::size_t n) {
  if (p == nullptr) return Allocate(n, 0);
  mi_heap_t* heap = t_heap;
  const std::size_t old_size = mi_usable_size(p);
  const bool old_in_arena = InArena(p);
  const int saved_errno = errno;
  void* q = heap != nullptr ? mi_heap_realloc(heap, p, n) : mi_realloc(p, n);
  if (q == nullptr && heap != nullptr) q = mi_heap_realloc(mi_heap_get_backing(), p, n);
  if (q == nullptr) return nullptr;  // p is untouched, as realloc promises
  errno = saved_errno;
  if (old_in_arena) AddLive(-static_cast<long long>(old_size));
  if (q != p) return Account(q);
  if (old_in_arena) AddLive(static_cast<long long>(mi_usable_size(q)));  // grown in place
  return q;
}

void Free(void* p) {
  Release(p);
  mi_free(p);
}

bool PowerOfTwo(std::size_t a) { return a != 0 && (a & (a - 1)) == 0; }
#endif  // VB_MEMORY_BUDGET

}  // namespace

#if VB_MEMORY_BUDGET
bool MemoryBudgetAvailable() { return true; }

std::string ReserveMemoryBudget(std::size_t bytes) {
  if (g_arena_id.load() >= 0) return "the memory budget's arena is already reserved";
  mi_arena_id_t id = 0;
  // Committed (read-write), not huge pages, and exclusive: only the heaps made for it
  // allocate there.
  const int err = mi_reserve_os_memory_ex(bytes, true, false, true, &id);
  if (err != 0) {
    char why[128];
    std::snprintf(why, sizeof(why), "cannot reserve a %zu MiB arena (error %d)", bytes >> 20, err);
    return why;
  }
  std::size_t size = 0;
  auto* begin = static_cast<char*>(mi_arena_area(id, &size));
  g_begin = reinterpret_cast<std::uintptr_t>(begin);
  g_end = reinterpret_cast<std::uintptr_t>(begin + size);
  g_arena_id = id;
  return "";
}

MemoryBudgetStats GetMemoryBudgetStats() {
  MemoryBudgetStats s;
  long long live = g_other_live.load();
  long long peaks = std::max(live, g_other_live_at_reset.load());
  const int n = std::min(g_num_threads.load(), kMaxBudgetThreads);
  for (int i = 0; i < n; ++i) {
    s.arena_allocations += g_threads[i].arena.load();
    s.heap_allocations += g_threads[i].heap.load();
    live += g_threads[i].live.load();
    peaks += g_threads[i].peak.load();
  }
  s.other_allocations = g_other_allocations.load();
  s.arena_live_bytes = static_cast<std::size_t>(std::max(0LL, live));
  s.arena_peak_bytes = static_cast<std::size_t>(std::max(live, peaks));
  s.arena_bytes = g_end.load() - g_begin.load();
  return s;
}

bool InMemoryBudget(const void* p) { return InArena(p); }

void ResetMemoryBudgetPeak() {
  // Racy against a thread raising its own peak at this moment, which then keeps the higher
  // value: the sum stays an upper bound.
  const int n = std::min(g_num_threads.load(), kMaxBudgetThreads);
  for (int i = 0; i < n; ++i) g_threads[i].peak = g_threads[i].live.load();
  g_other_live_at_reset = g_other_live.load();
}

MemoryBudgetScope::MemoryBudgetScope() {
  const int id = g_arena_id.load();
  if (id < 0 || t_heap != nullptr) return;  // no arena, or an outer scope already set one
  const int slot = g_num_threads.fetch_add(1);
  if (slot < kMaxBudgetThreads) t_counters = &g_threads[slot];  // else counted as another's
  t_heap = mi_heap_new_in_arena(id);
  heap_ = t_heap;
}

MemoryBudgetScope::~MemoryBudgetScope() {
  if (heap_ == nullptr) return;
  t_heap = nullptr;
  t_counters = nullptr;
  // Blocks still alive (a report handed to another thread) stay where they are, in the arena.
  mi_heap_delete(static_cast<mi_heap_t*>(heap_));
}
#else
bool MemoryBudgetAvailable() { return false; }
std::string ReserveMemoryBudget(std::size_t) {
  return "this build has no memory budget (sanitizers keep their own allocator)";
}
MemoryBudgetStats GetMemoryBudgetStats() { return {}; }
bool InMemoryBudget(const void*) { return false; }
void ResetMemoryBudgetPeak() {}
MemoryBudgetScope::MemoryBudgetScope() = default;
MemoryBudgetScope::~MemoryBudgetScope() = default;
#endif

std::string DescribeMemoryBudget(const MemoryBudgetStats& s) {
  if (s.arena_bytes == 0) return "no memory budget";
  char line[160];
  std::snprintf(line, sizeof(line),
                "arena %.1f of %zu MiB in use, peak %.1f MiB; %ld allocations from the arena, "
                "%ld from the heap",
                static_cast<double>(s.arena_live_bytes) / (1 << 20), s.arena_bytes >> 20,
                static_cast<double>(s.arena_peak_bytes) / (1 << 20), s.arena_allocations,
                s.heap_allocations);
  return line;
}

}  // namespace vb::daemon

#if VB_MEMORY_BUDGET
// The process's allocator: every entry point that hands out or takes back heap memory. All
// blocks are mimalloc's, so free() never needs to ask where a block came from.
using vb::daemon::Allocate;
using vb::daemon::Free;

extern "C" {
void* malloc(std::size_t n) { return Allocate(n, 0); }
void free(void* p) { Free(p); }
void* calloc(std::size_t count, std::size_t size) {
  return vb::daemon::AllocateZeroed(count, size);
}
void* realloc(void* p, std::size_t n) { return vb::daemon::Reallocate(p, n); }
void* reallocarray(void* p, std::size_t count, std::size_t size) {
  std::size_t n;
  if (__builtin_mul_overflow(count, size, &n)) {
    errno = ENOMEM;
    return nullptr;
  }
  return vb::daemon::Reallocate(p, n);
}
void* memalign(std::size_t alignment, std::size_t n) { return Allocate(n, alignment); }
void* aligned_alloc(std::size_t alignment, std::size_t n) {
  if (!vb::daemon::PowerOfTwo(alignment)) {
    errno = EINVAL;
    return nullptr;
  }
  return Allocate(n, alignment);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t n) {
  if (!vb::daemon::PowerOfTwo(alignment) || alignment % sizeof(void*) != 0) return EINVAL;
  void* p = Allocate(n, alignment);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t n) { return Allocate(n, static_cast<std::size_t>(getpagesize())); }
void* pvalloc(std::size_t n) {
  const auto page = static_cast<std::size_t>(getpagesize());
  return Allocate((n + page - 1) / page * page, page);
}
std::size_t malloc_usable_size(void* p) { return p == nullptr ? 0 : mi_usable_size(p); }
}  // extern "C"

// operator new and delete, so that C++ allocations take the same path (libstdc++'s and
// mimalloc's own versions would otherwise be chosen by library load order).
namespace {
void* NewOrThrow(std::size_t n, std::size_t alignment) {
  if (void* p = Allocate(n == 0 ? 1 : n, alignment)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t n) { return NewOrThrow(n, 0); }
void* operator new[](std::size_t n) { return NewOrThrow(n, 0); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return Allocate(n ? n : 1, 0); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept {
  return Allocate(n ? n : 1, 0);
}
void* operator new(std::size_t n, std::align_val_t a) {
  return NewOrThrow(n, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a) {
  return NewOrThrow(n, static_cast<std::size_t>(a));
}
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return Allocate(n ? n : 1, static_cast<std::size_t>(a));
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return Allocate(n ? n : 1, static_cast<std::size_t>(a));
}
void operator delete(void* p) noexcept { Free(p); }
void operator delete[](void* p) noexcept { Free(p); }
void operator delete(void* p, std::size_t) noexcept { Free(p); }
void operator delete[](void* p, std::size_t) noexcept { Free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { Free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { Free(p); }
void operator delete(void* p, std::align_val_t) noexcept { Free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { Free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { Free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { Free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { Free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { Free(p); }
#endif  // VB_MEMORY_BUDGET
