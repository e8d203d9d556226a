#pragma once

#include <Eigen/Core>

#include "morph/skeleton_graph.h"

namespace vb::morph {

/// Lengths are fractions of the cloud's bounding-box diagonal, so one set of defaults fits
/// any size and unit.
struct CloudSkeletonOptions {
  double voxel = 0.012;     ///< downsampling cell
  int neighbours = 8;       ///< k of the k-nearest-neighbour graph
  double band = 0.025;      ///< width of one geodesic level set
  double min_piece = 0.02;  ///< graph pieces smaller than this fraction of points are outliers
  int smoothing = 1;        ///< rounds of neighbour averaging against normal noise
  /// Level-set pieces with fewer points than this fraction of the median piece are noise
  /// and join the piece of the same band they touch most.
  double min_band_piece = 0.25;
};

/// Curve skeleton of an unorganised, noisy and possibly partial point cloud, with no surface
/// reconstruction: a geodesic level-set (Reeb graph) skeleton. The cloud is voxel-downsampled;
/// a k-nearest-neighbour graph approximates the surface (pieces separated by missing regions
/// are bridged at their closest points); geodesic distances run from an extremity (the point
/// farthest from an arbitrary start); every connected piece of each distance band becomes a
/// node at its centroid, and pieces touching across neighbouring bands are joined. Cycles
/// (from bridging or noise) are cut by a minimum spanning tree: a carcass skeleton is a tree.
/// Node support indexes the input cloud's columns.
/// @throws InputError when the cloud has fewer than 50 points or no extent, when its points
///   lie on too few spots to link, or when no linked piece holds options.min_piece of them.
SkeletonGraph CloudSkeleton(const Eigen::Matrix3Xd& points,
                            const CloudSkeletonOptions& options = {});

}  // namespace vb::morph
