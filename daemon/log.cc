#include "daemon/log.h"

#include <unistd.h>

#include <algorithm>
#include <cstdarg>
#include <cstdio>
#include <cstring>

namespace vb::daemon {
namespace {
bool g_simulation = false;
}  // namespace

void SetLogSimulation(bool simulation) { g_simulation = simulation; }
bool LogSimulation() { return g_simulation; }

void Log(Priority priority, const char* format, ...) {
  char line[1024];
  int n = std::snprintf(line, sizeof line, "<%d>virtualbutcherd: %s", static_cast<int>(priority),
                        g_simulation ? "SIMULATION: " : "");
  va_list args;
  va_start(args, format);
  const int body = std::vsnprintf(line + n, sizeof line - static_cast<std::size_t>(n), format, args);
  va_end(args);
  n = body < 0 ? n : std::min<int>(n + body, static_cast<int>(sizeof line) - 2);
  if (n == 0 || line[n - 1] != '\n') line[n++] = '\n';
  // One write: lines of the daemon's threads never interleave.
  [[maybe_unused]] const ssize_t written = write(STDERR_FILENO, line, static_cast<std::size_t>(n));
}

void LogLines(Priority priority, std::string_view text) {
  while (!text.empty()) {
    const std::size_t end = text.find('\n');
    const std::string_view one = text.substr(0, end);
    if (!one.empty()) Log(priority, "%.*s", static_cast<int>(one.size()), one.data());
    if (end == std::string_view::npos) break;
    text.remove_prefix(end + 1);
  }
}

}  // namespace vb::daemon
