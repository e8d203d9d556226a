#include "perception/marching_tetrahedra.h"

#include <gtest/gtest.h>

#include <numbers>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"

namespace vb::perception {
namespace {

struct Case {
  const char* name;
  double h;
};

class MarchingTetrahedraTest : public ::testing::TestWithParam<double> {};

TEST_P(MarchingTetrahedraTest, SphereIsClosedOrientedAndHasTheRightVolume) {
  const double h = GetParam();
  const auto sphere = [](const Eigen::Vector3d& p) { return p.norm() - 1.0; };
  const geometry::TriangleMesh mesh = MarchingTetrahedra(sphere, Eigen::Vector3d::Constant(-1.5),
                                                         Eigen::Vector3d::Constant(1.5), h);
  const geometry::TopologyReport r = geometry::AnalyzeTopology(mesh);
  EXPECT_TRUE(r.is_closed_manifold()) << r.Describe();
  EXPECT_TRUE(r.is_consistently_oriented()) << r.Describe();
  EXPECT_EQ(r.euler_characteristic(), 2);
  EXPECT_NEAR(geometry::SignedVolume(mesh), 4.0 / 3.0 * std::numbers::pi, 0.05 * 4.0);
}

// h = 0.25 puts grid nodes exactly on the sphere, the case the nudge exists for.
INSTANTIATE_TEST_SUITE_P(Spacings, MarchingTetrahedraTest, ::testing::Values(0.25, 0.13, 0.07));

TEST(MarchingTetrahedraTopologyTest, TorusHasGenusOneAndSeparateBlobsStaySeparate) {
  const auto torus = [](const Eigen::Vector3d& p) {
    return std::hypot(std::hypot(p.x(), p.y()) - 1.0, p.z()) - 0.35;
  };
  geometry::TriangleMesh mesh =
      MarchingTetrahedra(torus, {-1.6, -1.6, -0.6}, {1.6, 1.6, 0.6}, 0.08);
  geometry::TopologyReport r = geometry::AnalyzeTopology(mesh);
  EXPECT_TRUE(r.is_closed_manifold()) << r.Describe();
  EXPECT_EQ(r.euler_characteristic(), 0);
  EXPECT_EQ(r.genus(), 1);

  const auto blobs = [](const Eigen::Vector3d& p) {
    return std::min((p - Eigen::Vector3d(-1, 0, 0)).norm(), (p - Eigen::Vector3d(1, 0, 0)).norm()) -
           0.6;
  };
  mesh = MarchingTetrahedra(blobs, {-2, -1, -1}, {2, 1, 1}, 0.1);
  r = geometry::AnalyzeTopology(mesh);
  EXPECT_TRUE(r.is_closed_manifold()) << r.Describe();
  EXPECT_EQ(r.components, 2);
  EXPECT_GT(geometry::SignedVolume(mesh), 0.0);
}

}  // namespace
}  // namespace vb::perception
