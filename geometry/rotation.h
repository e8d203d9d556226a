#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <numbers>

namespace vb::geometry {

/// The angle of rotation @p R, degrees in [0, 180]. @pre R is a rotation matrix.
inline double RotationAngleDeg(const Eigen::Matrix3d& R) {
  return Eigen::AngleAxisd(R).angle() * 180.0 / std::numbers::pi;
}

}  // namespace vb::geometry
