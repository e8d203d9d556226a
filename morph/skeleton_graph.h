#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

namespace vb::morph {

/// A curve skeleton: nodes with positions and undirected edges. Each node may remember the
/// surface samples (mesh vertices or cloud points) it stands for.
struct SkeletonGraph {
  Eigen::Matrix3Xd nodes;  ///< 3 by #nodes
  std::vector<std::array<int, 2>> edges;
  std::vector<std::vector<int>> support;  ///< per node: indices of the samples it represents

  int num_nodes() const { return static_cast<int>(nodes.cols()); }
  /// Number of edges at each node.
  std::vector<int> Degrees() const;
};

/// The paper's feature nodes (eqs. 1-2): terminals (degree 1) and junctions (degree >= 3).
struct FeatureNodes {
  Eigen::Matrix3Xd terminals;  ///< 3 by #T
  Eigen::Matrix3Xd junctions;  ///< 3 by #J
  std::vector<std::vector<int>> terminal_support;
  std::vector<std::vector<int>> junction_support;

  int num_terminals() const { return static_cast<int>(terminals.cols()); }
  int num_junctions() const { return static_cast<int>(junctions.cols()); }
};

struct FeatureOptions {
  /// Terminal branches shorter than this (path length to their junction) are spurious and
  /// removed, repeatedly. Same unit as the skeleton (callers pass a fraction of the size).
  double min_branch_length = 0.05;
  /// Junctions closer than this along the skeleton are one junction (their mean).
  double junction_merge_distance = 0.08;
};

/// Prunes short spurious branches and merges nearby junctions, then lists the feature nodes.
/// A skeleton that is a single chain yields its two ends and no junction.
FeatureNodes ExtractFeatureNodes(const SkeletonGraph& skeleton, const FeatureOptions& options);

}  // namespace vb::morph
