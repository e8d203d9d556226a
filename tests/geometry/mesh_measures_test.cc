#include "geometry/mesh_measures.h"

#include <gtest/gtest.h>

#include <numbers>

#include "tests/support/test_meshes.h"

namespace vb::geometry {
namespace {

TEST(MeshMeasuresTest, BoxVolumeAreaAndDiagonal) {
  const TriangleMesh box = test::Box(2.0, 3.0, 4.0);
  EXPECT_NEAR(SignedVolume(box), 24.0, 1e-12);
  EXPECT_NEAR(SurfaceArea(box), 2 * (6.0 + 8.0 + 12.0), 1e-12);
  EXPECT_NEAR(BoundingBoxDiagonal(box.V), std::sqrt(29.0), 1e-12);
}

TEST(MeshMeasuresTest, VertexAreasShareEachFaceInThirds) {
  TriangleMesh mesh;
  mesh.V.resize(3, 5);  // two right triangles of areas 1 and 2 sharing vertices 0 and 1; 4 unused
  mesh.V << 0, 2, 0, 0, 9,  //
      0, 0, 1, -2, 9,       //
      0, 0, 0, 0, 9;
  mesh.F.resize(3, 2);
  mesh.F << 0, 0,  //
      1, 3,        //
      2, 1;
  const Eigen::VectorXd area = VertexAreas(mesh);
  ASSERT_EQ(area.size(), 5);
  EXPECT_NEAR(area[0], 1.0, 1e-12);
  EXPECT_NEAR(area[1], 1.0, 1e-12);
  EXPECT_NEAR(area[2], 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(area[3], 2.0 / 3.0, 1e-12);
  EXPECT_EQ(area[4], 0.0);
  const TriangleMesh box = test::Box(2.0, 3.0, 4.0);
  EXPECT_NEAR(VertexAreas(box).sum(), SurfaceArea(box), 1e-12);
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

TEST(MeshMeasuresTest, CurvatureSumsAreTwiceTheInverseRadiusOnASphere) {
  for (const double r : {0.5, 2.0}) {
    TriangleMesh sphere = test::Sphere(r, 3);
    // With the sphere's own normals every edge reads 1 / r.
    const Eigen::VectorXd exact = CurvatureSums(sphere, sphere.V / r);
    ASSERT_EQ(exact.size(), sphere.num_vertices());
    for (int i = 0; i < sphere.num_vertices(); ++i) EXPECT_NEAR(exact[i], 2.0 / r, 1e-9 / r);
    // With the mesh's area-weighted normals, which lean at the octahedron's six corners
    // (measured there: 3.37 against 4 at r = 0.5).
    const Eigen::VectorXd outward = CurvatureSums(sphere, VertexNormals(sphere));
    for (int i = 0; i < sphere.num_vertices(); ++i) EXPECT_NEAR(outward[i], 2.0 / r, 0.4 / r);
    EXPECT_NEAR(outward.mean(), 2.0 / r, 0.06 / r);
    // Normals turned inward: the surface bends towards them.
    sphere.F.row(1).swap(sphere.F.row(2));
    const Eigen::VectorXd inward = CurvatureSums(sphere, VertexNormals(sphere));
    EXPECT_NEAR(inward.mean(), -2.0 / r, 0.06 / r);
  }
}

TEST(MeshMeasuresTest, CurvatureSumsAreZeroOnAPlaneAndWhereNoEdgeIs) {
  TriangleMesh square;
  square.V.resize(3, 5);
  square.V << 0, 1, 1, 0, 5,  //
      0, 0, 1, 1, 5,          //
      0, 0, 0, 0, 5;
  square.F.resize(3, 2);
  square.F << 0, 0, 1, 2, 2, 3;
  const Eigen::VectorXd k = CurvatureSums(square, VertexNormals(square));
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(k[i], 0.0, 1e-12);
  EXPECT_EQ(k[4], 0.0);
}

}  // namespace
}  // namespace vb::geometry
