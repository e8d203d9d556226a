#include "io/mesh_measures.h"

#include <gtest/gtest.h>

#include <numbers>

#include "tests/support/test_meshes.h"

namespace vb::io {
namespace {

TEST(MeshMeasuresTest, BoxVolumeAreaAndDiagonal) {
  const TriangleMesh box = test::Box(2.0, 3.0, 4.0);
  EXPECT_NEAR(SignedVolume(box), 24.0, 1e-12);
  EXPECT_NEAR(SurfaceArea(box), 2 * (6.0 + 8.0 + 12.0), 1e-12);
  EXPECT_NEAR(BoundingBoxDiagonal(box.V), std::sqrt(29.0), 1e-12);
}

TEST(MeshMeasuresTest, VolumeIsIndependentOfPlacementAndFlipsWithOrientation) {
  TriangleMesh box = test::Box();
  box.V.colwise() += Eigen::Vector3d(1e4, -2e4, 3e4);
  EXPECT_NEAR(SignedVolume(box), 1.0, 1e-9);
  box.F.row(1).swap(box.F.row(2));
  EXPECT_NEAR(SignedVolume(box), -1.0, 1e-9);
}

TEST(MeshMeasuresTest, SphereNormalsPointOutwards) {
  const TriangleMesh sphere = test::Sphere(2.0, 3);
  const Eigen::Matrix3Xd N = VertexNormals(sphere);
  for (int i = 0; i < sphere.num_vertices(); ++i) {
    EXPECT_NEAR(N.col(i).norm(), 1.0, 1e-12);
    EXPECT_GT(N.col(i).dot(sphere.V.col(i).normalized()), 0.99);
  }
  // An inscribed polyhedron: a little smaller than the sphere, never larger.
  const double exact = 4.0 / 3.0 * std::numbers::pi * 8.0;
  EXPECT_LT(SignedVolume(sphere), exact);
  EXPECT_GT(SignedVolume(sphere), 0.97 * exact);
}

}  // namespace
}  // namespace vb::io
