#include "geometry/surface_sampling.h"

#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <vector>

namespace vb::geometry {
namespace {

// Two triangles in the plane z = 0, of areas 1 and 3, sharing no vertex.
TriangleMesh TwoTriangles() {
  TriangleMesh mesh;
  mesh.V.resize(3, 6);
  mesh.V << 0, 2, 0, 10, 13, 10,  //
      0, 0, 1, 0, 0, 2,           //
      0, 0, 0, 0, 0, 0;
  mesh.F.resize(3, 2);
  mesh.F << 0, 3,  //
      1, 4,        //
      2, 5;
  return mesh;
}

TEST(SurfaceSamplingTest, DrawsPointsOnTheFacesInProportionToTheirArea) {
  std::mt19937_64 engine(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::Matrix3Xd points, normals;
  constexpr int kCount = 40000;
  SampleSurface(
      TwoTriangles(), kCount, [&] { return unit(engine); }, &points, &normals);
  ASSERT_EQ(points.cols(), kCount);
  ASSERT_EQ(normals.cols(), kCount);
  int on_larger = 0;
  for (int i = 0; i < kCount; ++i) {
    const Eigen::Vector3d p = points.col(i);
    EXPECT_EQ(p.z(), 0.0);
    EXPECT_NEAR(normals.col(i).z(), 1.0, 1e-12);  // counter-clockwise seen from +z
    const bool larger = p.x() >= 10;
    on_larger += larger;
    // Inside its triangle: x - x0 >= 0, y >= 0 and x/(width) + y/(height) <= 1.
    const double x = larger ? (p.x() - 10) / 3 : p.x() / 2;
    const double y = larger ? p.y() / 2 : p.y();
    EXPECT_TRUE(x >= -1e-12 && y >= -1e-12 && x + y <= 1 + 1e-12) << p.transpose();
  }
  // Binomial(40000, 0.75): standard deviation 87 points.
  EXPECT_NEAR(on_larger, 0.75 * kCount, 350);
}

// Three draws per point, in the order face, u, v: the shape benchmark's targets depend on it.
TEST(SurfaceSamplingTest, UsesThreeDrawsPerPointFaceThenUThenV) {
  const std::vector<double> draws = {0.1, 0.2, 0.3, 0.5, 0.9, 0.6};
  std::size_t next = 0;
  Eigen::Matrix3Xd points, normals;
  SampleSurface(
      TwoTriangles(), 2, [&] { return draws.at(next++); }, &points, &normals);
  EXPECT_EQ(next, draws.size());
  // 0.1 of the area 4 falls in the first triangle (area 1): corner + 0.2 (b - a) + 0.3 (c - a).
  EXPECT_TRUE(points.col(0).isApprox(Eigen::Vector3d(0.4, 0.3, 0.0), 1e-12)) << points.col(0);
  // 0.5 of it in the second; u + v > 1 is folded back: u = 0.1, v = 0.4.
  EXPECT_TRUE(points.col(1).isApprox(Eigen::Vector3d(10.3, 0.8, 0.0), 1e-12)) << points.col(1);
}

TEST(SurfaceSamplingTest, RefusesASurfaceWithoutArea) {
  TriangleMesh flat = TwoTriangles();
  flat.V.row(1).setZero();  // every triangle collapses onto the x axis
  Eigen::Matrix3Xd points, normals;
  EXPECT_THROW(SampleSurface(
                   flat, 10, [] { return 0.5; }, &points, &normals),
               std::invalid_argument);
  EXPECT_THROW(SampleSurface(
                   TriangleMesh{}, 10, [] { return 0.5; }, &points, &normals),
               std::invalid_argument);
}

}  // namespace
}  // namespace vb::geometry
