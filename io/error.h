#pragma once

#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace vb {

/// Thrown for bad input found at start-up or when loading a file: the message names the
/// file, the key or line, and the offending value. Never thrown inside the frame loop.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace internal {
// Header-only, so that every library (geometry/ below io/ too) can check invariants.
[[noreturn]] inline void DemandFailed(const char* condition, const char* file, int line) {
  std::fprintf(stderr, "<2>virtualbutcher: invariant failed: %s at %s:%d\n", condition, file, line);
  std::abort();
}
}  // namespace internal

}  // namespace vb

/// Checks an invariant in every build type; a failure is a bug, so it aborts with a message.
#define VB_DEMAND(condition)                                        \
  do {                                                              \
    if (!(condition)) {                                             \
      ::vb::internal::DemandFailed(#condition, __FILE__, __LINE__); \
    }                                                               \
  } while (false)
