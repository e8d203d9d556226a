#pragma once

#include <Eigen/Core>
#include <vector>

// Eq. (12): trimming associations that break local rigidity.
namespace vb::morph {

struct AssociationFilterOptions {
  int neighbours = 8;  ///< k of the graph on the template's associated points
  /// Residuals below this are never trimmed, whatever the statistics say: r(i) is the mean
  /// squared relative change of an edge, so 0.1 is about 30 % local distortion. Without it,
  /// on clean targets, where residuals are tiny and skewed, mean + 2 std keeps chasing the
  /// tail and trims most of the associations.
  double min_residual = 0.1;
  /// Never trim more than this fraction of the associations.
  double max_trimmed_fraction = 0.5;
};

/// Eq. (12): local-rigidity filtering. Builds the k-nearest graph on the associated
/// template points, carries its edges to their partners, fits each point's rotation to its
/// edges and scores r(i), then trims the worst association and rescores only the points
/// whose neighbourhood lost it, until max(r) < mean(r) + 2 std(r). The fit is a rotation,
/// as in the paper, so @p a1 and @p a2 must be at the same scale (AlignDense works in the
/// template's frame after the coarse similarity).
/// @param[in] a1, a2 3 by M associated points on the template and on the target.
/// @return for each association, whether it is kept.
std::vector<bool> FilterAssociations(const Eigen::Matrix3Xd& a1, const Eigen::Matrix3Xd& a2,
                                     const AssociationFilterOptions& options = {});

}  // namespace vb::morph
