#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace vb::tools {

struct InputBenchOptions {
  /// Share of each limit the files are made to (1: the largest file the limits allow).
  double scale = 1.0;
  int repeats = 3;                  ///< reads per file; the table gives medians
  std::filesystem::path dir;        ///< scratch folder for the files (default: a temporary one)
  std::vector<std::string> only;    ///< these cases (by name), or all
  std::filesystem::path csv = "bench_inputs.csv";
};

/// `vbutcher bench inputs`: for each parser of a file the tools or the daemon read, the
/// largest file its limits allow (io/read_limits.h, the YAML, template and recording bounds)
/// is written, then read @p repeats times, each in a forked child so that its peak resident
/// memory is its own; prints a table of medians (time, peak memory above the child's start,
/// peak over file size, outcome) and writes one CSV row per read.
int RunInputBench(const InputBenchOptions& options);

}  // namespace vb::tools
