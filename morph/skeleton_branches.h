#pragma once

#include <Eigen/Core>
#include <vector>

#include "morph/skeleton_graph.h"

namespace vb::morph {

/// A limb of a skeleton: the shortest path along the skeleton from one of its feature
/// junctions (the root, where the limb meets the body) to a terminal (the tip).
struct SkeletonBranch {
  int terminal = -1;             ///< column of FeatureNodes::terminals
  std::vector<int> nodes;        ///< skeleton nodes, root first, tip last
  std::vector<double> distance;  ///< path length from the root to each node, skeleton units
  double length() const { return distance.empty() ? 0.0 : distance.back(); }
};

/// One branch per terminal of @p features that a path along @p skeleton joins to a junction
/// (the skeleton node nearest a feature junction); a skeleton without junctions yields none.
/// @pre @p features were extracted from @p skeleton.
std::vector<SkeletonBranch> TerminalBranches(const SkeletonGraph& skeleton,
                                             const FeatureNodes& features);

/// The point @p fraction of the way from a branch's root to its tip, along the skeleton, and
/// the skeleton node nearest it along the path (for its support).
Eigen::Vector3d PointAlong(const SkeletonGraph& skeleton, const SkeletonBranch& branch,
                           double fraction, int* nearest_node = nullptr);

}  // namespace vb::morph
