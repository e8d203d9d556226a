#include "io/error.h"

#include <cstdio>
#include <cstdlib>

namespace vb::internal {

void DemandFailed(const char* condition, const char* file, int line) {
  std::fprintf(stderr, "<2>virtualbutcher: invariant failed: %s at %s:%d\n", condition, file, line);
  std::abort();
}

}  // namespace vb::internal
