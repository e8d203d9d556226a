#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace vb::daemon {

/// Carcass numbers and job sequences that stay unique across daemon restarts, so the saw
/// never takes a restarted daemon's first job for a duplicate of the last one it accepted.
/// Each pair is written to a state file (write, fsync, rename) before the job can go out.
/// Without a readable state file the carcass numbers start from the clock (seconds since
/// 2024-01-01 UTC), which no earlier run can have reached unless it numbered more than one
/// carcass a second. Not thread safe (the job thread owns it).
class JobNumbers {
 public:
  struct Ids {
    std::uint32_t carcass = 0;
    std::uint8_t sequence = 0;
  };

  /// Reads @p state_file when it exists; an empty path keeps nothing (the clock alone).
  explicit JobNumbers(std::filesystem::path state_file);

  /// Non-empty when the state file could not be read: what happened and what was done.
  const std::string& warning() const { return warning_; }

  /// The next pair, after the state file holds it. @p error gets why it could not be
  /// written (the pair is still unique within this run, and still returned).
  Ids Next(std::string* error);

  /// The carcass number as operators see it ("C000042").
  static std::string Name(std::uint32_t carcass);

 private:
  std::filesystem::path path_;
  std::string temporary_;
  Ids last_;
  std::string warning_;
};

}  // namespace vb::daemon
