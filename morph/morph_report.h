#pragma once

#include <filesystem>

#include "morph/coarse_alignment.h"
#include "morph/template_model.h"

namespace vb::morph {

/// Writes what a morph did as JSON: per-stage timings, feature nodes found on each side, the
/// chosen association and its residual, and the solver summary.
/// @throws std::runtime_error when the file cannot be written.
void WriteMorphReport(const std::filesystem::path& path, const TemplateModel& model,
                      const CoarseResult& result);

}  // namespace vb::morph
