#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace vb::tools {

struct BenchOptions {
  std::string stage = "coarse";
  int pairs = 30;  ///< synthetic lamb targets per noise level
  std::vector<double> sigmas_mm = {0, 4, 16};
  std::uint64_t seed = 1;
  bool clouds = false;                        ///< also sampled clouds with missing regions
  std::vector<std::filesystem::path> shapes;  ///< extra closed meshes, re-posed by bends
  int shape_pairs = 5;
  std::string template_features = "levelset";  ///< levelset | mcf
  std::filesystem::path csv = "bench_coarse.csv";
};

/// `vbutcher bench coarse`: morphs synthetic targets with known correspondence and prints a
/// table (medians and means per noise level) and writes one CSV row per morph.
int RunBenchCommand(const BenchOptions& options);

}  // namespace vb::tools
