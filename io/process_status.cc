#include "io/process_status.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace vb::io {

long ProcessStatusKib(const char* field) {
  std::FILE* f = std::fopen("/proc/self/status", "r");
  if (f == nullptr) return -1;
  char line[256];
  long value = -1;
  const std::size_t n = std::strlen(field);
  while (std::fgets(line, sizeof(line), f) != nullptr)
    if (std::strncmp(line, field, n) == 0 && line[n] == ':') value = std::atol(line + n + 1);
  std::fclose(f);
  return value;
}

}  // namespace vb::io
