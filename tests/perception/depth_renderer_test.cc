#include "perception/depth_renderer.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/support/test_meshes.h"

namespace vb::perception {
namespace {

// A camera at the rig origin looking along +x (optical z = rig x).
Eigen::Isometry3d LookingAlongX() {
  return LookAt(Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 0));
}

TEST(DepthRendererTest, SphereDepthMatchesGeometry) {
  const Intrinsics k;
  DepthRenderer dut(k, LookingAlongX());
  geometry::TriangleMesh sphere = test::Sphere(0.2, 5);
  sphere.V.row(0).array() += 1.5;  // centre 1.5 m ahead
  dut.Render(sphere);
  const auto centre = static_cast<std::size_t>(std::lround(k.cy) * k.width + std::lround(k.cx));
  // The nearest point of the sphere (1.3 m), within the tessellation's sag.
  EXPECT_NEAR(dut.depth_m()[centre], 1.3, 0.002);
  EXPECT_NEAR(dut.cos_incidence()[centre], 1.0, 0.01);
  // Silhouette: angular radius asin(0.2 / 1.5); pixels well outside see nothing.
  const double radius_px = k.fx * std::tan(std::asin(0.2 / 1.5));
  const int u_out = static_cast<int>(k.cx + radius_px + 4);
  const int u_in = static_cast<int>(k.cx + radius_px - 4);
  const int v = static_cast<int>(k.cy);
  EXPECT_EQ(dut.depth_m()[static_cast<std::size_t>(v * k.width + u_out)], 0.0f);
  EXPECT_GT(dut.depth_m()[static_cast<std::size_t>(v * k.width + u_in)], 1.3f);
  // Near the silhouette the view is grazing.
  EXPECT_LT(dut.cos_incidence()[static_cast<std::size_t>(v * k.width + u_in)], 0.5f);
}

TEST(DepthRendererTest, FloorIsSeenWhereNothingElseIs) {
  const Intrinsics k;
  // 1 m above the floor, looking 30 degrees down.
  const Eigen::Isometry3d X_RigCam =
      LookAt(Eigen::Vector3d(0, 0, 1.0), Eigen::Vector3d(std::sqrt(3.0), 0, 0));
  DepthRenderer dut(k, X_RigCam);
  dut.Render(geometry::TriangleMesh{}, 0.0);
  // Along the optical axis the floor is 2 m away (1 m / sin 30 deg); pixel (u, v) looks
  // along d_C = ((u - cx) / fx, (v - cy) / fy, 1).
  for (const auto& [u, v] : {std::pair{320, 240}, std::pair{100, 400}, std::pair{600, 50}}) {
    const Eigen::Vector3d d_C((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
    const double expected = -1.0 / X_RigCam.linear().row(2).dot(d_C);
    EXPECT_NEAR(dut.depth_m()[static_cast<std::size_t>(v * k.width + u)], expected, 1e-5);
  }
  EXPECT_NEAR(dut.depth_m()[static_cast<std::size_t>(240 * k.width + 320)], 2.0, 0.005);
  EXPECT_NEAR(dut.cos_incidence()[static_cast<std::size_t>(240 * k.width + 320)], 0.5, 0.005);
  // The top row looks above the horizon at 30 deg - 22.8 deg half-FOV... still down: hit.
  EXPECT_GT(dut.depth_m()[static_cast<std::size_t>(k.cx)], 2.0f);
}

}  // namespace
}  // namespace vb::perception
