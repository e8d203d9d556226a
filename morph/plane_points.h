#pragma once

#include <Eigen/Core>
#include <span>

#include "morph/point_index.h"
#include "morph/worker_pool.h"

// Points on a noisy cloud's local planes (eq. 14's targets), and how many points they average.
namespace vb::morph {

/// Target points a plane point averages on a target @p relative_noise times as noisy as the
/// level @p fewest points suffice for: fewest x relative_noise^2, so that the plane points
/// keep that level's noise, and never fewer than @p fewest nor more than @p most (past which
/// curved parts flatten).
int NeighboursForNoise(int fewest, int most, double relative_noise);

/// How far inside a noisy surface a ball's centroid sits, to first order: sigma^2 (k1 + k2)
/// towards the concave side (the points the noise pushed there crowd), for noise @p sigma
/// and curvature sum @p curvature_sum (positive where convex). At most sigma either way.
double CurvatureOffset(double curvature_sum, double sigma);

/// A point on each target point's local plane for eq. (14): the centroid of its @p k nearest
/// points within @p radius (which averages sensor noise along the normal away, over a patch
/// no wider than the radius, so coarser features survive), and, if @p correct_curvature,
/// moved along the point's normal by the mean offset of those neighbours' points from their
/// own centroids. A centroid on a convex patch lies inside the surface by about the curvature
/// times the squared radius of the neighbourhood, nearly the same at neighbouring points;
/// adding that back removes the bias and keeps the averaging.
/// A plane point lies within 2 @p radius of its point (the centroid within one radius, the
/// correction at most one more).
/// @param[in] points, normals 3 by N (unit normals); @p index over @p points; k >= 1.
/// @param pool when given, the points are shared among its threads; the result is the same
///   on any number of threads.
Eigen::Matrix3Xd PlanePoints(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                             const PointIndex& index, int k, double radius, bool correct_curvature,
                             WorkerPool* pool = nullptr);

/// PlanePoints' result for the listed points only: column m is the plane point of point
/// which[m], bit for bit what PlanePoints gives it. Costs about the listed points' share of
/// PlanePoints (with the correction, also their neighbours' centroids), so a caller that reads
/// one region of a large cloud pays for that region.
/// @pre every entry of @p which lies in [0, N); the rest as PlanePoints.
Eigen::Matrix3Xd PlanePointsOf(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                               const PointIndex& index, int k, double radius,
                               bool correct_curvature, std::span<const int> which,
                               WorkerPool* pool = nullptr);

}  // namespace vb::morph
