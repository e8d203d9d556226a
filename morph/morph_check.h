#pragma once

#include <Eigen/Core>
#include <limits>
#include <span>
#include <string>

#include "morph/coarse_alignment.h"
#include "morph/dense_alignment.h"
#include "morph/template_model.h"

namespace vb::morph {

/// Signs, computed without ground truth, that a morph went wrong as a whole (a carcass
/// placed upside down, a limb taken for another, a region folded). Lengths are fractions
/// of the template's size.
struct MorphCheck {
  /// The chosen placement's disagreement over that of the best placement turned elsewhere,
  /// both when the choice was made (CoarseResult::choice_disagreement);
  /// near 1 the coarse stage could not tell two placements apart, 0 when there was none.
  double ambiguity = 0.0;
  /// Fraction of target points farther than MorphCheckOptions::explained_distance (plus
  /// noise_allowance times the noise the dense stage estimated) from the morphed template's
  /// vertices: the part of the carcass the morph did not cover.
  double unexplained = 0.0;
  /// 99th percentile of the target points' distances to the morphed template's nearest
  /// vertices, in template sizes: how far the farthest part of the carcass the morph left
  /// uncovered lies (a limb the template put elsewhere, or something attached to the carcass
  /// such as a gambrel), when that part holds more than 1 % of the points. NaN when there is
  /// no target, no morphed vertex or no size.
  double reach = std::numeric_limits<double>::quiet_NaN();
  /// The target's noise the dense stage estimated (DenseResult::noise: a standard deviation),
  /// in template sizes: what unexplained and reach allow for. Not a sign.
  double noise = 0.0;
  /// The most reach a right morph shows from the noise and the template's vertex spacing
  /// alone, template sizes: MorphCheckOptions::reach_noise noise levels plus the template's
  /// mean edge length over sqrt(3) (the farthest a point of an equilateral triangle lies from
  /// its nearest corner). The confidence reads reach less this. Not a sign.
  double reach_allowance = 0.0;
  /// 90th percentile of |log(edge length morphed / edge length rest)| after the global
  /// scale: how far the morph had to stretch the template to fit.
  double stretch = 0.0;
  /// The morphed template's size over the template's own: the RMS distance of its vertices
  /// from their centroid, morphed over rest (target units over template units). Far from 1
  /// the target is in other units (millimetres read as metres) or another kind of body.
  double size = 1.0;
  /// In [0, 1]: 1 unless one of the signs above passes its limit, then falling to 0; 0 when
  /// the reach or its allowance cannot be read. The pipeline multiplies every transferred
  /// cut's own confidence by it.
  double confidence = 1.0;
  /// Which sign lowered the confidence most, for an operator ("" when none did).
  std::string concern;
};

/// Where the whole-morph check starts to lower the confidence, and where it reaches 0. The
/// limits sit between what good and wrong placements measured (docs/decisions.md, "Knowing
/// when not to cut"; docs/method.md, "After the morph").
struct MorphCheckOptions {
  /// A target point is unexplained farther than explained_distance plus noise_allowance
  /// times the estimated noise (DenseResult::noise) from the morphed template; both in
  /// template sizes and noise levels.
  double explained_distance = 0.02;
  double noise_allowance = 0.75;
  /// Confidence falls linearly from 1 at ambiguity_start to 0 at 1: from just above the
  /// largest ambiguity of a right lamb placement on the rig's recordings (0.98;
  /// docs/decisions.md).
  double ambiguity_start = 0.99;
  /// Confidence halves at this unexplained fraction (and falls as its square beyond).
  double unexplained_scale = 0.08;
  /// Noise levels reach allows for: the 99th percentile of the distance of points with
  /// Gaussian noise from their surface is 2.58 standard deviations.
  double reach_noise = 2.6;
  /// Confidence falls linearly from 1 at reach_start to 0 at reach_end, reach less
  /// MorphCheck::reach_allowance, template sizes: from well above the most a right lamb
  /// morph shows on the line's poses (0.005) to where limbs put elsewhere on the shape
  /// benchmark lie (docs/decisions.md, "The check counts the cloud's farthest points").
  double reach_start = 0.03;
  double reach_end = 0.06;
  /// Confidence falls linearly from 1 at stretch_start to 0 at stretch_end: from 1.2 times
  /// the largest stretch of a right lamb morph on the benchmark (0.17, clouds at 8 mm) to
  /// about the least of a lamb forced upside down (0.25 to 0.34).
  double stretch_start = 0.20;
  double stretch_end = 0.30;
  /// Confidence is 0 when MorphCheck::size lies outside [min_size, max_size]. Carcasses of
  /// one kind differ in size by far less than 2 (the synthetic lambs 0.8 to 1.2, lambs of
  /// 15 to 30 kg by 1.26 in length); a unit mistake is a factor of 10 or 1000.
  double min_size = 0.5;
  double max_size = 2.0;
};

/// Reads the target points the dense stage used (DenseResult::target).
/// @param nearest_vertex for each of those points, the dense mesh's nearest vertex
///   (NearestEach), or empty to find them here.
MorphCheck CheckMorph(const TemplateModel& model, const CoarseResult& coarse,
                      const DenseResult& dense, const MorphCheckOptions& options = {},
                      std::span<const int> nearest_vertex = {});

/// One line for a person (the daemon's job line, `vbutcher morph`): the confidence, then each
/// sign, then the concern when there is one, e.g. "0.93 (ambiguity 0.120, unexplained
/// 0.012, reach 0.021 (noise and spacing 0.018), stretch 0.110, size 1.004)".
std::string DescribeCheck(const MorphCheck& check);

}  // namespace vb::morph
