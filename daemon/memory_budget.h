#pragma once

#include <cstddef>
#include <string>

namespace vb::daemon {

/// virtualbutcherd's fixed memory budget. At start the daemon reserves one arena of
/// `memory.arena_mib` (config) from the OS; its loop threads (main, capture, job) then take
/// every allocation from that arena: their own, the morph's per-solve matrices, Eigen's
/// temporaries, LCM's message buffers. Nothing a loop thread does after start asks the
/// process heap or the OS for memory, so a job cannot grow the daemon, and a steady state
/// that allocates nothing new is something a test can check (`tests/daemon/memory_budget_test`,
/// and per job in the daemon's log).
///
/// How: the daemon executable links `daemon/memory_budget.cc`, which replaces malloc, free
/// and their relatives and operator new/delete with mimalloc (a well-kept allocator). A loop
/// thread's allocations go to its own mimalloc heap in the reserved arena; any other thread's
/// (OpenNI2's and its drivers') to mimalloc's ordinary heaps. Should the arena ever be full,
/// the allocation is still served, from the ordinary heap, and counted in
/// `heap_allocations`: the daemon never crashes for its budget, and the count says the
/// budget is too small. Sanitizer builds keep their own allocator and have no budget
/// (Available() is false).

/// What the budget's threads took, process-wide, since the arena was reserved.
struct MemoryBudgetStats {
  long arena_allocations = 0;        ///< allocations by budget threads that landed in the arena
  long heap_allocations = 0;         ///< allocations by budget threads that did not (arena full)
  long other_allocations = 0;        ///< allocations by every other thread (not ours to budget)
  std::size_t arena_live_bytes = 0;  ///< bytes in the arena not yet freed
  /// An upper bound on the most it held at once since ResetMemoryBudgetPeak (or the start):
  /// the sum of each budget thread's peak.
  std::size_t arena_peak_bytes = 0;
  std::size_t arena_bytes = 0;  ///< its size (0: no arena)
};

/// True when this binary replaces the allocator (not in sanitizer builds, not in binaries
/// that do not link memory_budget.cc).
bool MemoryBudgetAvailable();

/// Reserves the arena, once per process; later calls fail. Returns "" or why it could not
/// (the OS refused the reservation, or there is no budget in this build).
std::string ReserveMemoryBudget(std::size_t bytes);

MemoryBudgetStats GetMemoryBudgetStats();

/// Starts the peak (MemoryBudgetStats::arena_peak_bytes) again from what the arena holds
/// now; the daemon's job thread does so as each job starts.
void ResetMemoryBudgetPeak();

/// True when @p p points into the arena.
bool InMemoryBudget(const void* p);

/// For the lifetime of this object, the calling thread allocates from the arena (a no-op
/// when there is no arena). Create one at the top of a loop thread, on that thread.
class MemoryBudgetScope {
 public:
  MemoryBudgetScope();
  ~MemoryBudgetScope();
  MemoryBudgetScope(const MemoryBudgetScope&) = delete;
  MemoryBudgetScope& operator=(const MemoryBudgetScope&) = delete;

 private:
  void* heap_ = nullptr;
};

/// One line for the log: "arena 41.2 of 512 MiB in use, peak 88.0 MiB; 0 heap allocations".
std::string DescribeMemoryBudget(const MemoryBudgetStats& stats);

}  // namespace vb::daemon
