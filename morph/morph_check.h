#pragma once

#include <Eigen/Core>
#include <string>

#include "morph/coarse_alignment.h"
#include "morph/dense_alignment.h"
#include "morph/template_model.h"

namespace vb::morph {

/// Signs, computed without ground truth, that a morph went wrong as a whole (a carcass
/// placed upside down, a limb taken for another, a region folded). Lengths are fractions
/// of the template's size.
struct MorphCheck {
  /// Coarse disagreement over that of the best placement turned elsewhere (CoarseResult);
  /// near 1 the coarse stage could not tell two placements apart, 0 when there was none.
  double ambiguity = 0.0;
  /// Fraction of target points farther than MorphCheckOptions::explained_distance (plus
  /// three times the noise the dense stage estimated) from the morphed template's vertices:
  /// the part of the carcass the morph did not cover.
  double unexplained = 0.0;
  /// 90th percentile of |log(edge length morphed / edge length rest)| after the global
  /// scale: how far the morph had to stretch the template to fit.
  double stretch = 0.0;
  /// In [0, 1]: 1 unless one of the signs above passes its limit, then falling to 0. The
  /// pipeline multiplies every transferred cut's own confidence by it.
  double confidence = 1.0;
  /// Which sign lowered the confidence most, for an operator ("" when none did).
  std::string concern;
};

/// Limits measured with `vbutcher bench full` (README, "Knowing when not to cut"): on 60
/// lamb targets the wrong placements (cut planes 30-460 mm off) had ambiguity 0.99-1.0,
/// unexplained 0.09-0.35 or stretch 0.25-0.34; the good ones at most 0.9, 0.08 and 0.24.
struct MorphCheckOptions {
  /// A target point is unexplained farther than explained_distance plus noise_allowance
  /// times the estimated noise from the morphed template (both template sizes). The
  /// allowance was 3 while the noise estimate read a third of the true sigma at 16 mm. With
  /// the estimate reading the true sigma, on 10 lamb clouds with missing regions at sigma
  /// 16 mm (jobs sent / sent with a cut more than 10 mm off): seed 1, 2 / 2 before, 0 / 0 at
  /// 0.75, 4 / 2 at 1; seed 2, 3 / 3 before and at 0.75. Lower noise is not affected.
  double explained_distance = 0.02;
  double noise_allowance = 0.75;
  /// Confidence falls linearly from 1 at ambiguity_start to 0 at 1.
  double ambiguity_start = 0.92;
  /// Confidence halves at this unexplained fraction (and falls as its square beyond).
  double unexplained_scale = 0.08;
  /// Confidence falls linearly from 1 at stretch_start to 0 at stretch_end.
  double stretch_start = 0.26;
  double stretch_end = 0.36;
};

/// Reads the target points the dense stage used (DenseResult::target).
MorphCheck CheckMorph(const TemplateModel& model, const CoarseResult& coarse,
                      const DenseResult& dense, const MorphCheckOptions& options = {});

}  // namespace vb::morph
