#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "io/annotations.h"
#include "morph/cut_band_fit.h"
#include "morph/cut_line.h"

// Every cut placed along its normal at once, from all the band readings.
namespace vb::morph {

/// What TransferCuts learns of one cut before the cuts are placed together.
struct CutReading {
  LineExtent extent;
  /// The morph's scale about the band; 0 when no band fit was possible (no normals' turn,
  /// or no band), and then the cut is not moved.
  double scale = 0.0;
  std::optional<BandSlide> band;  // the band's own reading, template units
};

/// The slides of all cuts from their band readings (template units): the posterior mean and
/// standard deviation under a zero-mean Gaussian prior with covariance
///   K_ij = sigma^2 exp(-(d_ij / length)^2) n_i.n_j,
/// d_ij the distance between the cuts' line centroids and n their expert normals, and each
/// reading's variance its standard error squared plus model_error squared. Cuts without a
/// reading get what the others say of them. Returns false, every slide 0, when no cut has a
/// reading.
bool PlaceTogether(const io::Annotations& annotations, const std::vector<CutReading>& readings,
                   double sigma, double length, double model_error, Eigen::VectorXd* mean,
                   Eigen::VectorXd* deviation);

}  // namespace vb::morph
