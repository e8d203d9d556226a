#pragma once

#include <filesystem>
#include <string>

namespace vb::tools {

struct MorphCommandOptions {
  std::filesystem::path template_path;
  std::filesystem::path target_path;
  std::filesystem::path out_path;
  std::string stage = "coarse";  ///< coarse | full (full equals coarse until the dense stage lands)
  std::filesystem::path report_path;
};

/// `vbutcher morph`: loads the template and target, morphs, writes the deformed template
/// (template vertex order and faces) and optionally a JSON report. Returns the exit code.
int RunMorphCommand(const MorphCommandOptions& options);

}  // namespace vb::tools
