#pragma once

#include <Eigen/Core>

namespace vb::geometry {

/// An oriented plane: the points x with normal.dot(x - point) == 0. The normal is unit length.
struct Plane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();

  /// Signed distance of @p x, positive on the side the normal points to.
  double SignedDistance(const Eigen::Vector3d& x) const { return normal.dot(x - point); }
};

}  // namespace vb::geometry
