#pragma once

#include <Eigen/Core>
#include <vector>

#include "morph/point_index.h"

namespace vb::morph {

/// Unit normals of a point cloud from principal axes (the direction of least spread),
/// oriented to agree with the normal of the nearest @p reference point (a surface already
/// close to the cloud, such as the posed template), so they point outward wherever the
/// reference does.
///
/// With @p passes = 1 the axes are those of each point's @p k nearest neighbours. Every
/// further pass widens the neighbourhood: it replaces each point's moments (count, sum and
/// sum of outer products of the points it covers) by the mean of its k nearest neighbours'
/// moments, so after p passes a point's axes are those of a bell-shaped weighting of about
/// k x p points around it. Noisy clouds need that many: the normal's error falls with the
/// points averaged, and a pass costs k additions a point where a k x p nearest-neighbour
/// query costs several times more.
/// @param[in] points 3 by N; @param[in] reference, reference_normals 3 by M, M >= 1.
/// @pre k >= 3, passes >= 1, @p index over @p points.
Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, const PointIndex& index, int k,
                                 int passes, const Eigen::Matrix3Xd& reference,
                                 const Eigen::Matrix3Xd& reference_normals);

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
/// @param[in] points, normals 3 by N (unit normals); @p index over @p points; k >= 1.
Eigen::Matrix3Xd PlanePoints(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                             const PointIndex& index, int k, double radius, bool correct_curvature);

/// What EstimateNoise read.
struct NoiseEstimate {
  double sigma = 0.0;  ///< standard deviation along the normal; 0 when no point could be fitted
  /// The cloud was read at every stride-th point: 1 unless it was denser than its noise.
  int stride = 1;
};

/// The standard deviation of a cloud's noise along its surface, from the cloud alone. At
/// every n-th point (about @p samples of them) a quadratic height field is fitted to the
/// point's @p k nearest neighbours within @p radius, in their principal frame and without
/// the point itself; the estimate is 1.4826 x the median of the points' offsets from their
/// fits. Points with fewer than 12 neighbours in reach are skipped. The quadratic
/// takes out the curvature that a plane reads as noise, leaving the point out keeps the fit
/// from absorbing its noise, and the radius keeps a coarse surface (a mesh of a few thousand
/// vertices) from reading its shape as noise.
/// The neighbours must also reach well beyond the noise: the k nearest of a point pushed out
/// are those pushed out with it, and on a cloud dense against its noise they read it low
/// (half of it when they reach 1.3 sigma). So while they reach less than 4 times the reading,
/// the cloud is read again at every second point (then every 4th, ... 16th), which widens
/// their reach by 1.4 each time, until the reading grows by less than 10 % or the radius
/// stops the reach growing; the last reading is kept, with its stride.
/// @pre samples >= 1, k >= 10, radius > 0, @p index over @p points.
NoiseEstimate EstimateNoise(const Eigen::Matrix3Xd& points, const PointIndex& index, int samples,
                            int k, double radius);

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
