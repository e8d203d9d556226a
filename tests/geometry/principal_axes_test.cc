#include "geometry/principal_axes.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

namespace vb::geometry {
namespace {

// The eight corners of a 2 x 6 x 4 box, turned and moved: its axes are the box's edges,
// shortest first, and its mean is the box's centre.
TEST(PrincipalAxesTest, BoxCornersGiveTheBoxEdgesShortestFirst) {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d centre(5.0, -2.0, 1.5);
  const Eigen::Vector3d half(1.0, 3.0, 2.0);
  Eigen::Matrix3Xd corners(3, 8);
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d sign((c & 1) ? 1 : -1, (c & 2) ? 1 : -1, (c & 4) ? 1 : -1);
    corners.col(c) = centre + R * sign.cwiseProduct(half);
  }
  const PrincipalAxes principal = FitPrincipalAxes(corners);
  EXPECT_LT((principal.mean - centre).norm(), 1e-12);
  // Shortest (x: 2), middle (z: 4), longest (y: 6); each up to its sign.
  EXPECT_NEAR(std::abs(principal.axes.col(0).dot(R.col(0))), 1.0, 1e-12);
  EXPECT_NEAR(std::abs(principal.axes.col(1).dot(R.col(2))), 1.0, 1e-12);
  EXPECT_NEAR(std::abs(principal.axes.col(2).dot(R.col(1))), 1.0, 1e-12);
  EXPECT_LT((principal.axes.transpose() * principal.axes - Eigen::Matrix3d::Identity()).norm(),
            1e-12);
}

}  // namespace
}  // namespace vb::geometry
