#include "geometry/mesh_topology.h"

#include <gtest/gtest.h>

#include "geometry/mesh_measures.h"
#include "tests/support/test_meshes.h"

namespace vb::geometry {
namespace {

TEST(MeshTopologyTest, ClosedShapesAreOrientedManifoldsOfGenusZero) {
  for (const TriangleMesh& mesh : {test::Box(), test::Tetrahedron(), test::Sphere(1.0, 3)}) {
    const TopologyReport r = AnalyzeTopology(mesh);
    EXPECT_TRUE(r.is_closed_manifold()) << r.Describe();
    EXPECT_TRUE(r.is_consistently_oriented()) << r.Describe();
    EXPECT_EQ(r.components, 1);
    EXPECT_EQ(r.euler_characteristic(), 2);
    EXPECT_EQ(r.genus(), 0);
  }
}

TEST(MeshTopologyTest, ATorusHasOneHandle) {
  const TopologyReport torus = AnalyzeTopology(test::Torus(1.0, 0.3, 24, 12));
  EXPECT_TRUE(torus.is_single_closed_surface()) << torus.Describe();
  EXPECT_EQ(torus.euler_characteristic(), 0);
  EXPECT_EQ(torus.genus(), 1);
  EXPECT_GT(SignedVolume(test::Torus(1.0, 0.3, 24, 12)), 0.0);  // wound outward
}

TEST(MeshTopologyTest, FindsHolesFlipsAndLooseVertices) {
  TriangleMesh open = test::Box();
  open.F.conservativeResize(3, open.num_faces() - 1);
  TopologyReport r = AnalyzeTopology(open);
  EXPECT_EQ(r.boundary_edges, 3);
  EXPECT_FALSE(r.is_closed_manifold());

  TriangleMesh flipped = test::Box();
  std::swap(flipped.F(1, 0), flipped.F(2, 0));
  r = AnalyzeTopology(flipped);
  EXPECT_EQ(r.inconsistent_edges, 3);
  EXPECT_FALSE(r.is_consistently_oriented());
  EXPECT_NE(r.Describe().find("3 inconsistently oriented edges"), std::string::npos);

  TriangleMesh loose = test::Box();
  loose.V.conservativeResize(3, loose.num_vertices() + 1);
  loose.V.col(loose.num_vertices() - 1).setZero();
  EXPECT_EQ(AnalyzeTopology(loose).unreferenced_vertices, 1);
}

TEST(MeshTopologyTest, FindsNonManifoldEdgesAndVertices) {
  // Two tetrahedra sharing one vertex: every edge is fine, the shared vertex is not.
  TriangleMesh a = test::Tetrahedron();
  TriangleMesh pair;
  pair.V.resize(3, 7);
  pair.V.leftCols(4) = a.V;
  pair.V.rightCols(3) = a.V.rightCols(3).array() + 5.0;
  pair.V.col(0).setZero();
  pair.F.resize(3, 8);
  pair.F.leftCols(4) = a.F;
  pair.F.rightCols(4) = a.F.array() + 3;
  for (int f = 4; f < 8; ++f) {
    for (int k = 0; k < 3; ++k) {
      if (pair.F(k, f) == 3) pair.F(k, f) = 0;
    }
  }
  TopologyReport r = AnalyzeTopology(pair);
  EXPECT_EQ(r.nonmanifold_edges, 0);
  EXPECT_EQ(r.nonmanifold_vertices, 1);
  EXPECT_EQ(r.components, 2);
  EXPECT_FALSE(r.is_closed_manifold());

  // A fin: a third face on an edge of the box.
  TriangleMesh fin = test::Box();
  fin.V.conservativeResize(3, 9);
  fin.V.col(8) = Eigen::Vector3d(0.5, -1.0, -1.0);
  fin.F.conservativeResize(3, 13);
  fin.F.col(12) = Eigen::Vector3i(0, 1, 8);
  r = AnalyzeTopology(fin);
  EXPECT_EQ(r.nonmanifold_edges, 1);
  EXPECT_FALSE(r.is_closed_manifold());
}

TEST(MeshTopologyTest, CountsDegenerateFaces) {
  TriangleMesh mesh = test::Box();
  mesh.F(2, 0) = mesh.F(0, 0);
  EXPECT_EQ(AnalyzeTopology(mesh).degenerate_faces, 1);
}

}  // namespace
}  // namespace vb::geometry
