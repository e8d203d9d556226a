#include "tests/support/allocation_counter.h"

#include <execinfo.h>
#include <link.h>

#include <stdio.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>

#if defined(__SANITIZE_ADDRESS__)
#define VB_COUNT_MALLOC 0
#else
#define VB_COUNT_MALLOC 1
#endif

namespace {

std::atomic<long> g_allocations{0};
std::atomic<long> g_excluded{0};
std::atomic<long> g_excluded_frees{0};

struct Range {
  std::uintptr_t begin = 0, end = 0;
};
constexpr int kMaxRanges = 8;
Range g_ranges[kMaxRanges];
std::atomic<int> g_num_ranges{0};
thread_local bool t_in_hook = false;
// The call stacks of the last few counted allocations, for a failing test to print.
constexpr int kKeptStacks = 8;
void* g_stacks[kKeptStacks][24];
int g_stack_depth[kKeptStacks];
std::atomic<int> g_next_stack{0};

// True when code of an excluded library is on the call stack.
bool InExcludedLibrary(void* const* frames, int n) {
  const int ranges = g_num_ranges.load(std::memory_order_acquire);
  for (int i = 0; i < n; ++i) {
    const auto pc = reinterpret_cast<std::uintptr_t>(frames[i]);
    for (int r = 0; r < ranges; ++r)
      if (pc >= g_ranges[r].begin && pc < g_ranges[r].end) return true;
  }
  return false;
}

// Counts a free made by an excluded library, so a test can see its allocations balance.
void CountFree() {
  if (t_in_hook || g_num_ranges.load(std::memory_order_acquire) == 0) return;
  t_in_hook = true;
  void* frames[24];
  if (InExcludedLibrary(frames, backtrace(frames, 24)))
    g_excluded_frees.fetch_add(1, std::memory_order_relaxed);
  t_in_hook = false;
}

// Walks the stack (only when libraries are excluded) and counts the allocation.
void Count() {
  if (t_in_hook) return;  // the stack walk's own allocations are the counter's, not the test's
  if (g_num_ranges.load(std::memory_order_acquire) == 0) {
    g_allocations.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  t_in_hook = true;
  void* frames[24];
  const int n = backtrace(frames, 24);
  const bool excluded = InExcludedLibrary(frames, n);
  (excluded ? g_excluded : g_allocations).fetch_add(1, std::memory_order_relaxed);
  if (!excluded) {
    const int slot = g_next_stack.fetch_add(1) % kKeptStacks;
    std::memcpy(g_stacks[slot], frames, sizeof(void*) * static_cast<std::size_t>(n));
    g_stack_depth[slot] = n;
  }
  t_in_hook = false;
}

struct Search {
  const char* fragment;
  bool found = false;
};

int AddRanges(dl_phdr_info* info, std::size_t, void* data) {
  auto* search = static_cast<Search*>(data);
  if (info->dlpi_name == nullptr || std::strstr(info->dlpi_name, search->fragment) == nullptr)
    return 0;
  for (int i = 0; i < info->dlpi_phnum; ++i) {
    const ElfW(Phdr)& ph = info->dlpi_phdr[i];
    if (ph.p_type != PT_LOAD || !(ph.p_flags & PF_X)) continue;
    const int r = g_num_ranges.load();
    if (r == kMaxRanges) return 1;
    g_ranges[r] = {info->dlpi_addr + ph.p_vaddr, info->dlpi_addr + ph.p_vaddr + ph.p_memsz};
    g_num_ranges.store(r + 1, std::memory_order_release);
    search->found = true;
  }
  return 0;
}

}  // namespace

namespace vb::test {
long AllocationCount() { return g_allocations.load(std::memory_order_relaxed); }
long ExcludedAllocationCount() { return g_excluded.load(std::memory_order_relaxed); }
long ExcludedFreeCount() { return g_excluded_frees.load(std::memory_order_relaxed); }

void PrintCountedStacks(int fd) {
  const int total = g_next_stack.load();
  t_in_hook = true;  // printing allocates; those are not the test's
  for (int i = std::max(0, total - kKeptStacks); i < total; ++i) {
    dprintf(fd, "-- counted allocation %d:\n", i);
    backtrace_symbols_fd(g_stacks[i % kKeptStacks], g_stack_depth[i % kKeptStacks], fd);
  }
  t_in_hook = false;
}

bool ExcludeLibrary(const char* path_fragment) {
  void* warm[2];
  backtrace(warm, 2);  // the first call loads the unwinder (and allocates): do it here
  Search search{path_fragment};
  dl_iterate_phdr(AddRanges, &search);
  return search.found;
}
}  // namespace vb::test

#if VB_COUNT_MALLOC
// glibc's own entry points; defining malloc and friends here interposes them for the whole
// process, shared libraries included (Eigen and OpenNI2 allocate with malloc).
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);

void free(void* p) {
  if (p != nullptr) CountFree();
  __libc_free(p);
}
void* malloc(std::size_t n) {
  Count();
  return __libc_malloc(n);
}
void* calloc(std::size_t n, std::size_t size) {
  Count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t n) {
  Count();
  return __libc_realloc(p, n);
}
void* aligned_alloc(std::size_t alignment, std::size_t n) {
  Count();
  return __libc_memalign(alignment, n);
}
void* memalign(std::size_t alignment, std::size_t n) {
  Count();
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t n) {
  Count();
  void* p = __libc_memalign(alignment, n);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
}  // extern "C"
#else
// Under ASan only operator new is ours to replace; GCC cannot see it is malloc-based.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  Count();
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept {
  if (p != nullptr) CountFree();
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept { operator delete(p); }
void operator delete[](void* p) noexcept { operator delete(p); }
void operator delete[](void* p, std::size_t) noexcept { operator delete(p); }
// The nothrow forms too (std::stable_sort's buffer): left to ASan, a block it allocates would be
// freed by the delete above, and ASan stops on the mismatch.
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  Count();
  return std::malloc(n == 0 ? 1 : n);
}
void* operator new[](std::size_t n, const std::nothrow_t& tag) noexcept {
  return operator new(n, tag);
}
void operator delete(void* p, const std::nothrow_t&) noexcept { operator delete(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { operator delete(p); }
#endif
