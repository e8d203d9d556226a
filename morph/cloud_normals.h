#pragma once

#include <Eigen/Core>
#include <vector>

#include "morph/point_index.h"
#include "morph/worker_pool.h"

// Normals of a point cloud.
namespace vb::morph {

/// Unit normals of a point cloud from principal axes (the direction of least spread), each
/// signed to agree with its column of @p hints (such as the normal of the nearest vertex of a
/// surface already close to the cloud, the posed template's), so they point outward wherever
/// the hints do. With no hints the sign is arbitrary (for uses that compare directions only,
/// such as the posture fit's normal compatibility).
///
/// With @p passes = 1 the axes are those of each point's @p k nearest neighbours. Every
/// further pass widens the neighbourhood: it replaces each point's moments (count, sum and
/// sum of outer products of the points it covers) by the mean of its k nearest neighbours'
/// moments, so after p passes a point's axes are those of a bell-shaped weighting of about
/// k x p points around it. Noisy clouds need that many: the normal's error falls with the
/// points averaged, and a pass costs k additions a point where a k x p nearest-neighbour
/// query costs several times more.
/// @param[in] points 3 by N; @param[in] hints 3 by N, or 3 by 0 for none.
/// @pre k >= 3, passes >= 1, @p index over @p points.
/// @param pool when given, the points are shared among its threads; the result is the same
///   on any number of threads.
Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, const PointIndex& index, int k,
                                 int passes, const Eigen::Matrix3Xd& hints,
                                 WorkerPool* pool = nullptr);

/// EstimateNormals' passes for a cloud whose noise is @p relative_noise times the noise one
/// pass suffices for: (relative_noise)^2 rounded (the normal's error falls with the square root
/// of the points averaged), at least 1 and at most @p max_passes (at least 1).
int NormalPassesForNoise(double relative_noise, int max_passes);

/// Fits @p normals again over wider neighbourhoods: each point j with @p counts[j] > 0 gets
/// the direction of least spread of its counts[j] nearest points (itself included; all
/// points when there are fewer) that lie within @p radii[j] of it, signed to agree with its
/// normal before. Other normals are left as they are. A point with fewer than 3 points in
/// reach keeps its normal.
/// @pre counts.size() == radii.size() == points.cols() == normals->cols(), @p index over
///   @p points; radii in the points' units, radii[j] >= 0 (not NaN) where counts[j] > 0.
/// @param pool when given, the points are shared among its threads; the result is the same
///   on any number of threads.
void RefitNormals(const Eigen::Matrix3Xd& points, const PointIndex& index,
                  const std::vector<int>& counts, const std::vector<double>& radii,
                  Eigen::Matrix3Xd* normals, WorkerPool* pool = nullptr);

}  // namespace vb::morph
