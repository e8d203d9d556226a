#pragma once

#include <string>
#include <vector>

#include "geometry/mesh_measures.h"
#include "geometry/triangle_mesh.h"
#include "io/annotations.h"
#include "morph/coarse_alignment.h"
#include "morph/cut_transfer.h"
#include "morph/dense_alignment.h"
#include "morph/morph_check.h"
#include "morph/part_volumes.h"
#include "morph/target_cleaning.h"
#include "morph/template_model.h"

namespace vb::morph {

struct MorphOptions {
  /// Stray points and detached clutter taken out of the target first.
  CleaningOptions clean;
  CoarseOptions coarse;
  DenseOptions dense;
  CutTransferOptions cuts;
  PartVolumeOptions parts;
  MorphCheckOptions check;
  /// A morph past it stops and fails with "abandoned: ..." (the daemon's job deadline and
  /// shutdown), but for MorphCarcass's second try of pieces apart, whose first morph stands.
  /// It overrides the stages' own.
  MorphDeadline deadline;
};

/// One carcass through the whole method: coarse posture, dense surface, cut transfer and
/// virtual cutting.
struct CarcassResult {
  bool ok = false;
  std::string error;  ///< why not, when !ok
  /// How the target was read (every n-th point of a cloud far denser than the template) and
  /// what was taken out of it before the stages (they see the rest).
  CleaningSummary cleaning;
  CoarseResult coarse;
  DenseResult dense;
  /// The morph as a whole; every cut's confidence already includes check.confidence.
  MorphCheck check;
  std::vector<TransferredCut> cuts;
  std::vector<geometry::PartMeasure> parts;  ///< in the annotations' part order
  double cuts_seconds = 0;                   ///< check, cut transfer and virtual cutting
  double seconds = 0;
};

/// The morph's first steps, as MorphCarcass takes them: a cloud far denser than @p model's
/// vertices thinned and the clutter taken out (options.clean, CleanTarget), then AlignCoarse
/// (options.coarse) on the rest, with the cleaning's kd-tree when the target was read whole
/// and nothing went. For a cloud without normals the noise is read (options.dense's reading)
/// and sets AlignCoarse's fit_normal_passes as it sets the dense stage's normal passes. A
/// target with non-finite points or a normal count of its own is not cleaned, for the stages
/// to name the fault. @p cleaned receives the cloud (and normals) the later stages are to use
/// and what was left out. Throws what AlignCoarse throws.
/// @param pool threads to share the work with (none: the caller's alone).
CoarseResult CleanAndAlignCoarse(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                                 const Eigen::Matrix3Xd& normals, const MorphOptions& options,
                                 WorkerPool* pool, CleanedTarget* cleaned);

/// The stages after the coarse one, from @p coarse: dense surface, the whole-morph check, cut
/// transfer and virtual cutting. MorphCarcass calls it after AlignCoarse; the benchmark also
/// calls it from a coarse result it fitted to the ground truth. Never throws on a bad target.
/// @param pool threads to share the work with (none: the caller's alone).
CarcassResult MorphFromCoarse(const TemplateModel& model, const io::Annotations& annotations,
                              CoarseResult coarse, const Eigen::Matrix3Xd& target,
                              const Eigen::Matrix3Xd& normals, const MorphOptions& options = {},
                              WorkerPool* pool = nullptr);

/// Morphs @p model onto @p target (points and, optionally, unit normals of the same count)
/// and carries @p annotations over: CleanAndAlignCoarse, then MorphFromCoarse. When the
/// cleaning dropped small pieces apart from the body, options.clean.rejoin_detached holds and
/// the deadline leaves 1.5 times the first morph's time, the cloud with them put back is
/// morphed too, and that morph is returned when its check's confidence is above 0 and, if
/// the first succeeded, no lower than the first's, with an unexplained share, reach and
/// stretch no larger (cleaning.rejoined counts the points; cleaning.tried_back and its
/// seconds say it was tried); else the first, which stands even when the deadline passes
/// during the second. Never throws on a bad target: the result says why.
/// @param pool threads to share the work with (none: the caller's alone); see Morpher,
///   which keeps one.
CarcassResult MorphCarcass(const TemplateModel& model, const io::Annotations& annotations,
                           const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& normals,
                           const MorphOptions& options = {}, WorkerPool* pool = nullptr);

}  // namespace vb::morph
