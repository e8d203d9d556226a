#include "io/read_limits.h"

#include <algorithm>
#include <mutex>

#include "io/error.h"

namespace vb::io {
namespace {

std::mutex& LimitsMutex() {
  static std::mutex mutex;
  return mutex;
}

ReadLimits& Limits() {
  static ReadLimits limits;
  return limits;
}

}  // namespace

ReadLimits DefaultReadLimits() {
  const std::lock_guard<std::mutex> lock(LimitsMutex());
  return Limits();
}

void SetDefaultReadLimits(const ReadLimits& limits) {
  const std::lock_guard<std::mutex> lock(LimitsMutex());
  Limits() = limits;
}

void CheckLimit(const std::string& source, const std::string& element, std::int64_t count,
                std::int64_t limit, const char* option) {
  if (count <= limit) return;
  throw InputError(source + ": " + std::to_string(count) + " " + element +
                   ", more than the limit of " + std::to_string(limit) + " (" + option +
                   " raises it)");
}

std::string Excerpt(std::string_view text, std::size_t max) {
  std::string out;
  const std::size_t n = std::min(text.size(), max);
  out.reserve(n + 32);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    out += c >= 0x20 && c < 0x7f ? static_cast<char>(c) : '?';
  }
  if (text.size() > max) out += "... (" + std::to_string(text.size()) + " characters)";
  return out;
}

}  // namespace vb::io
