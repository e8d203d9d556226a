#pragma once

#include <filesystem>
#include <vector>

#include "geometry/plane_cut.h"
#include "io/annotations.h"
#include "morph/coarse_alignment.h"
#include "morph/cut_transfer.h"
#include "morph/dense_alignment.h"
#include "morph/morph_check.h"
#include "morph/target_cleaning.h"
#include "morph/template_model.h"

namespace vb::morph {

/// Writes what a morph did as JSON: per-stage timings, feature nodes found on each side, the
/// chosen association and its residual, and the solver summary; with @p dense (may be null)
/// also each dense round (pairs found and kept, plane distance, solver); with @p cleaning
/// (may be null) how the target was read and what was left out (spacing in the target's
/// units, reported as metres as the rest).
/// @throws std::runtime_error when the file cannot be written.
void WriteMorphReport(const std::filesystem::path& path, const TemplateModel& model,
                      const CoarseResult& result, const DenseResult* dense = nullptr,
                      const CleaningSummary* cleaning = nullptr);

/// Writes the transferred cuts as JSON (target units and frame): per cut its name, plane
/// (point, unit normal towards the part before it), fit RMS, coverage, gap, confidence and
/// the cut line; per part its name, volume and outer area; the whole-morph check.
/// @throws std::runtime_error when the file cannot be written.
void WriteCutsReport(const std::filesystem::path& path, const io::Annotations& annotations,
                     const std::vector<TransferredCut>& cuts,
                     const std::vector<geometry::PartMeasure>& parts, const MorphCheck& check);

}  // namespace vb::morph
