#pragma once

#include <filesystem>
#include <string>

namespace vb::tools {

struct MorphCommandOptions {
  std::filesystem::path template_path;
  std::filesystem::path target_path;
  std::filesystem::path out_path;
  std::string stage = "coarse";  ///< coarse | full
  std::filesystem::path report_path;
  std::filesystem::path annotations_path;  ///< with --stage full: cuts to transfer
  std::filesystem::path cuts_path;         ///< transferred cuts and part measures (JSON)
};

/// `vbutcher morph`: loads the template and target, morphs, writes the deformed template
/// (template vertex order and faces) and optionally a JSON report; with annotations and the
/// full stage, transfers the cuts and writes them. Returns the exit code: 0 done, 2 bad
/// input (thrown as InputError), 3 the morph failed on this target.
int RunMorphCommand(const MorphCommandOptions& options);

}  // namespace vb::tools
