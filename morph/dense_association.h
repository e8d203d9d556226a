#pragma once

#include <Eigen/Core>
#include <vector>

#include "morph/point_index.h"

// Eq. (11): the dense stage's normal-aware pairing of template and target points.
namespace vb::morph {

struct DenseAssociationOptions {
  /// Target points searched per template point (the kd-tree subset of eq. 11).
  int candidates = 12;
  /// Lambda of eq. (11), per unit length of the frame the points are in (the template's
  /// normalised frame: its bounding-box diagonal is 1). At 25, a 4 % longer distance costs
  /// as much as normals 90 degrees apart.
  double lambda = 25.0;
  /// Associations longer than this are dropped (the target has no surface there).
  double max_distance = 0.06;
  /// Associations whose normals disagree more than this (cosine) are dropped: the nearest
  /// surface is the far side of a thin limb.
  double min_normal_cosine = 0.3;
};

/// Pairs of the dense association (A1, A2 of section II-B).
struct DenseAssociation {
  std::vector<int> source;  ///< index of the template point
  std::vector<int> target;  ///< index of the target point
  int size() const { return static_cast<int>(source.size()); }
};

/// Eq. (11): for each of the @p samples of the (posed) template points, the target point j
/// among its options.candidates nearest minimising lambda |v_i - v_j| - o_i . o_j.
DenseAssociation AssociateDense(const Eigen::Matrix3Xd& source,
                                const Eigen::Matrix3Xd& source_normals,
                                const std::vector<int>& samples, const Eigen::Matrix3Xd& target,
                                const Eigen::Matrix3Xd& target_normals,
                                const PointIndex& target_index,
                                const DenseAssociationOptions& options = {});

}  // namespace vb::morph
