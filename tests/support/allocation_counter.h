#pragma once

namespace vb::test {

/// Heap allocations made by this process (every thread) since it started: calls to malloc,
/// calloc, realloc, aligned allocations and operator new, except those attributed to an
/// excluded library (below). Linking this file into a test binary replaces those functions
/// with counting ones; under AddressSanitizer, whose allocator must stay in charge, only
/// operator new is counted.
long AllocationCount();

/// Allocations attributed to excluded libraries (their code is on the call stack), and the
/// frees they made: equal counts over a stretch mean the library's memory did not grow.
long ExcludedAllocationCount();
long ExcludedFreeCount();

/// From now on, allocations made with code of the loaded shared library whose path contains
/// @p path_fragment on the call stack are counted apart (ExcludedAllocationCount). For a
/// third-party library whose internals we cannot change (OpenNI2's frame queue), so that a
/// test can still hold our own code to zero. Returns false if no such library is loaded.
bool ExcludeLibrary(const char* path_fragment);

/// Prints the call stacks of the last few counted allocations (made while a library was
/// excluded) to @p fd, for a test that found some.
void PrintCountedStacks(int fd);

/// Counts the allocations made in its scope (Drake's LimitMalloc, without the abort).
class AllocationScope {
 public:
  AllocationScope()
      : start_(AllocationCount()),
        excluded_start_(ExcludedAllocationCount()),
        excluded_frees_start_(ExcludedFreeCount()) {}
  long count() const { return AllocationCount() - start_; }
  long excluded() const { return ExcludedAllocationCount() - excluded_start_; }
  long excluded_frees() const { return ExcludedFreeCount() - excluded_frees_start_; }

 private:
  long start_;
  long excluded_start_;
  long excluded_frees_start_;
};

}  // namespace vb::test
