#pragma once

#include <Eigen/Core>

#include "morph/point_index.h"

// A cloud's sensor noise, read from the cloud alone.
namespace vb::morph {

/// What EstimateNoise read.
struct NoiseEstimate {
  double sigma = 0.0;  ///< standard deviation along the normal; 0 when no point could be fitted
  /// The cloud was read at every stride-th point: 1 unless it was denser than its noise.
  int stride = 1;
  /// Points per unit of area (the cloud's units squared) of the cloud as read, every
  /// stride-th point: the median over the samples of n / (pi r^2), r the distance to the
  /// farthest of the n neighbours a sample's fit used. 0 when no point could be fitted.
  double density = 0.0;
};

/// A normal distribution's standard deviation over its median absolute deviation: the noise
/// read from a median distance.
inline constexpr double kMadToSigma = 1.4826;

/// Fewest and most neighbours a noise reading fits to: at least twice the quadratic's six
/// coefficients; at most what its fits hold inline.
inline constexpr int kMinNoiseNeighbours = 12;
inline constexpr int kMaxNoiseNeighbours = 500;

/// The standard deviation of a cloud's noise along its surface, from the cloud alone. At
/// every n-th point (about @p samples of them) a quadratic height field is fitted to the
/// point's @p k nearest neighbours within @p radius, in their principal frame and without
/// the point itself; the estimate is 1.4826 x the median of the points' offsets from their
/// fits. Points with fewer than kMinNoiseNeighbours in reach are skipped. The quadratic
/// takes out the curvature that a plane reads as noise, leaving the point out keeps the fit
/// from absorbing its noise, and the radius keeps a coarse surface (a mesh of a few thousand
/// vertices) from reading its shape as noise.
/// The neighbours must also reach well beyond the noise: the k nearest of a point pushed out
/// are those pushed out with it, and on a cloud dense against its noise they read it low
/// (half of it when they reach 1.3 sigma). So while they reach less than 4 times the reading,
/// the cloud is read again at every second point (then every 4th, ... 16th), which widens
/// their reach by 1.4 each time, until the reading grows by less than 10 % or the radius
/// stops the reach growing; the last reading is kept, with its stride.
/// @pre samples >= 1, kMinNoiseNeighbours <= k <= kMaxNoiseNeighbours, radius > 0, @p index
/// over @p points.
NoiseEstimate EstimateNoise(const Eigen::Matrix3Xd& points, const PointIndex& index, int samples,
                            int k, double radius);

}  // namespace vb::morph
