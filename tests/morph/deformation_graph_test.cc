#include "morph/deformation_graph.h"

#include <gtest/gtest.h>

#include "geometry/mesh_measures.h"
#include "tests/support/implicit_shapes.h"
#include "tests/support/test_meshes.h"

namespace vb::morph {
namespace {

// Two prongs 0.1 apart joined at the bottom, 1 tall: their tips are close in space but
// 2 apart along the surface.
geometry::TriangleMesh Fork() {
  return test::CapsuleUnion({{{-0.12, 0, 0}, {-0.12, 0, 1}, 0.07},
                             {{0.12, 0, 0}, {0.12, 0, 1}, 0.07},
                             {{-0.12, 0, 0}, {0.12, 0, 0}, 0.07}},
                            0.025);
}

TEST(DeformationGraphTest, NodesAreSpacedVerticesAndEdgesFollowTheSurface) {
  const geometry::TriangleMesh fork = Fork();
  DeformationGraphOptions options;
  const DeformationGraph g = BuildDeformationGraph(fork, options);
  const double spacing = options.node_spacing * geometry::BoundingBoxDiagonal(fork.V);
  ASSERT_GT(g.num_nodes(), 20);
  for (int j = 0; j < g.num_nodes(); ++j) {
    EXPECT_EQ(g.nodes.col(j), fork.V.col(g.node_vertex[static_cast<std::size_t>(j)]));
    EXPECT_EQ(static_cast<int>(g.neighbours[static_cast<std::size_t>(j)].size()),
              options.graph_neighbours);
    for (int k = j + 1; k < g.num_nodes(); ++k)
      EXPECT_GE((g.nodes.col(j) - g.nodes.col(k)).norm(), spacing);
  }
  // Euclidean k-NN would join the prongs near their tips; the geodesic search must not.
  for (const auto& [a, b] : g.edges) {
    const bool upper = g.nodes(2, a) > 0.4 && g.nodes(2, b) > 0.4;
    EXPECT_FALSE(upper && g.nodes(0, a) * g.nodes(0, b) < 0)
        << "edge " << a << "-" << b << " jumps between prongs";
  }
}

TEST(DeformationGraphTest, VertexWeightsAreLocalPartitionsOfUnity) {
  const geometry::TriangleMesh fork = Fork();
  DeformationGraphOptions options;
  const DeformationGraph g = BuildDeformationGraph(fork, options);
  const NodeWeights w = VertexWeights(fork, g, options);
  ASSERT_EQ(w.nodes.cols(), fork.num_vertices());
  for (int v = 0; v < fork.num_vertices(); ++v) {
    EXPECT_NEAR(w.weights.col(v).sum(), 1.0, 1e-12);
    EXPECT_GE(w.weights.col(v).minCoeff(), 0.0);
    for (Eigen::Index k = 0; k < w.nodes.rows(); ++k) {
      if (w.weights(k, v) == 0.0) continue;
      // A vertex high on one prong is moved only by nodes of that prong.
      if (fork.V(2, v) > 0.4) {
        EXPECT_GT(fork.V(0, v) * g.nodes(0, w.nodes(k, v)), 0.0);
      }
    }
  }
}

TEST(DeformationGraphTest, FindsBridgesOnlyWhereTheGraphHasThem) {
  const geometry::TriangleMesh sphere = test::Sphere(1.0, 4);
  DeformationGraphOptions options;
  EXPECT_TRUE(BuildDeformationGraph(sphere, options).bridges.empty());
  // With one neighbour per node the graph is a forest: every edge is a bridge.
  options.graph_neighbours = 1;
  const DeformationGraph sparse = BuildDeformationGraph(sphere, options);
  EXPECT_EQ(sparse.bridges.size(), sparse.edges.size());
}

}  // namespace
}  // namespace vb::morph
