#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

namespace vb::geometry {

/// The centroid of a point set and its principal axes.
struct PrincipalAxes {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  /// Unit axes as columns, in ascending order of the spread along them: column 0 is the
  /// shortest axis, column 2 the longest. Each axis's sign is arbitrary.
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
};

/// The centroid of the columns of @p points and the eigenvectors of their scatter about it.
/// Units are those of @p points. @pre points has at least one column.
inline PrincipalAxes FitPrincipalAxes(const Eigen::Matrix3Xd& points) {
  PrincipalAxes out;
  out.mean = points.rowwise().mean();
  const Eigen::Matrix3Xd centred = points.colwise() - out.mean;
  out.axes =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(centred * centred.transpose()).eigenvectors();
  return out;
}

}  // namespace vb::geometry
