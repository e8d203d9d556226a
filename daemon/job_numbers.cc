#include "daemon/job_numbers.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iomanip>

namespace vb::daemon {
namespace {

constexpr char kHeader[] = "vbutcher-job-state 1";
constexpr std::int64_t kEpoch2024 = 1704067200;  // 2024-01-01T00:00:00Z, Unix seconds

std::uint32_t ClockFloor() {
  const std::int64_t now = std::chrono::duration_cast<std::chrono::seconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
  return static_cast<std::uint32_t>(std::max<std::int64_t>(1, now - kEpoch2024));
}

}  // namespace

JobNumbers::JobNumbers(std::filesystem::path state_file) : path_(std::move(state_file)) {
  const std::uint32_t floor = ClockFloor();
  last_ = {floor - 1, static_cast<std::uint8_t>(floor)};
  if (path_.empty()) return;
  temporary_ = path_.string() + ".new";
  std::ifstream in(path_);
  if (!in) {
    warning_ = "job state " + path_.string() + " does not exist yet: carcass numbers start " +
               "from the clock (" + Name(floor) + ")";
    return;
  }
  char first_line[64] = {};  // bounded: a hostile state file is not read whole
  in.getline(first_line, sizeof first_line);
  const std::string header = first_line;
  std::string carcass_key, sequence_key;
  std::int64_t carcass = -1, sequence = -1;
  if (in && header == kHeader)
    in >> std::setw(16) >> carcass_key >> carcass >> std::setw(16) >> sequence_key >> sequence;
  if (header != kHeader || carcass_key != "carcass" || sequence_key != "sequence" || !in ||
      carcass < 0 || carcass > 0xFFFFFFFELL || sequence < 0 || sequence > 255) {
    warning_ = "job state " + path_.string() + ": not a '" + kHeader +
               "' file with 'carcass N' and 'sequence N' lines; carcass numbers start from " +
               "the clock (" + Name(floor) + ")";
    return;
  }
  last_ = {static_cast<std::uint32_t>(carcass), static_cast<std::uint8_t>(sequence)};
}

JobNumbers::Ids JobNumbers::Next(std::string* error) {
  error->clear();
  last_.carcass = last_.carcass == 0xFFFFFFFFu ? 1 : last_.carcass + 1;
  last_.sequence = static_cast<std::uint8_t>(last_.sequence + 1);
  if (path_.empty()) return last_;
  char text[96];
  const int length = std::snprintf(text, sizeof text, "%s\ncarcass %" PRIu32 "\nsequence %u\n",
                                   kHeader, last_.carcass, static_cast<unsigned>(last_.sequence));
  // Written in place of the old one only once it is on disk, so a crash leaves one or the
  // other, never half of one. No heap allocation (the job thread's budget).
  const int fd = open(temporary_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  bool ok =
      fd >= 0 && write(fd, text, static_cast<std::size_t>(length)) == length && fsync(fd) == 0;
  const int saved = errno;
  if (fd >= 0) close(fd);
  ok = ok && rename(temporary_.c_str(), path_.c_str()) == 0;
  if (!ok) {
    *error = "cannot write the job state " + path_.string() + ": " +
             std::strerror(saved != 0 ? saved : errno);
  }
  return last_;
}

std::string JobNumbers::Name(std::uint32_t carcass) {
  char name[16];
  std::snprintf(name, sizeof name, "C%06" PRIu32, carcass);
  return name;
}

}  // namespace vb::daemon
