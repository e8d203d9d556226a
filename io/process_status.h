#pragma once

namespace vb::io {

/// A memory figure of this process from /proc/self/status, in KiB ("VmRSS", "VmHWM", ...),
/// or -1 when it cannot be read. For logs and benchmarks.
long ProcessStatusKib(const char* field);

}  // namespace vb::io
