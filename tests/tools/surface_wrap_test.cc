// The benchmark's geometry: CGAL's alpha wrap of open soups, and anchoring points on a
// surface so that they follow it into another pose.
#include "tools/shape_set/surface_wrap.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "tests/support/test_meshes.h"

namespace vb::tools {
namespace {

TEST(SurfaceAnchorTest, PointsNearASurfaceComeBackWhereTheyWere) {
  const geometry::TriangleMesh sphere = test::Sphere(1.0, 3);
  // Points off the surface, inside and outside.
  Eigen::Matrix3Xd points = 1.03 * sphere.V.leftCols(40);
  points.rightCols(20) *= 0.95;
  const Eigen::Matrix3Xd placed = PlaceAnchors(AnchorOnSurface(points, sphere), sphere);
  EXPECT_LT((placed - points).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(SurfaceAnchorTest, ARigidMotionOfTheSurfaceMovesTheAnchoredPointsWithIt) {
  const geometry::TriangleMesh box = test::Box(2.0, 1.0, 0.5);
  const Eigen::Matrix3Xd points = 1.1 * box.V;
  const std::vector<SurfaceAnchor> anchors = AnchorOnSurface(points, box);
  const Eigen::Isometry3d X = Eigen::Translation3d(0.3, -1.0, 2.0) *
                              Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized());
  geometry::TriangleMesh moved = box;
  moved.V = X * box.V;  // Eigen applies the isometry to every column
  const Eigen::Matrix3Xd placed = PlaceAnchors(anchors, moved);
  EXPECT_LT((placed - X * points).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(SurfaceWrapTest, AnOpenSoupOfTwoPiecesBecomesOneClosedManifold) {
  // Two boxes, each with two faces missing, apart by less than the wrap's alpha.
  geometry::TriangleMesh soup = test::Box(1.0, 1.0, 1.0);
  const int faces = soup.num_faces();
  geometry::TriangleMesh other = soup;
  other.V.row(0).array() += 1.005;
  soup.V.conservativeResize(3, soup.V.cols() + other.V.cols());
  soup.V.rightCols(other.V.cols()) = other.V;
  soup.F.conservativeResize(3, 2 * faces - 4);
  soup.F.rightCols(faces - 2) = (other.F.leftCols(faces - 2).array() + other.num_vertices()).matrix();
  const geometry::TriangleMesh wrap = WrapSurface(soup, {.alpha = 0.02, .offset = 0.002});
  const geometry::TopologyReport topology = geometry::AnalyzeTopology(wrap);
  EXPECT_TRUE(topology.is_closed_manifold()) << topology.Describe();
  EXPECT_TRUE(topology.is_consistently_oriented()) << topology.Describe();
  EXPECT_EQ(topology.components, 1);
  EXPECT_GT(geometry::SignedVolume(wrap), 0.0);  // outward
}

}  // namespace
}  // namespace vb::tools
