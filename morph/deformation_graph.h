#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

#include "geometry/triangle_mesh.h"

namespace vb::morph {

/// Lengths are fractions of the template's bounding-box diagonal.
struct DeformationGraphOptions {
  double node_spacing = 0.045;  ///< minimum distance between graph nodes
  int graph_neighbours = 6;     ///< mu: geodesic neighbours per node (Algorithm 1)
  int vertex_neighbours = 4;    ///< nodes influencing each vertex (eqs. 9-10)
};

/// The embedded-deformation graph (G, E) of a template mesh. Nodes are template vertices;
/// edges join each node to its mu nearest nodes along the mesh (not through the air, so
/// nearby legs stay independent).
struct DeformationGraph {
  std::vector<int> node_vertex;              ///< template vertex of each node
  Eigen::Matrix3Xd nodes;                    ///< 3 by #nodes positions g_j
  std::vector<std::vector<int>> neighbours;  ///< per node, its mu geodesic nearest nodes
  std::vector<std::array<int, 2>> edges;     ///< undirected, each once
  std::vector<std::array<int, 2>> bridges;   ///< edges whose removal splits the graph (DFS)

  int num_nodes() const { return static_cast<int>(nodes.cols()); }
};

/// The most nodes that may act on one point: a compiled template with more is refused, since
/// the solver's work and memory grow with the square of it.
inline constexpr int kMaxNodesPerPoint = 16;

/// Fixed-width node influences: column i lists the nodes acting on point i and their
/// weights (summing to 1); unused slots have node -1 and weight 0.
/// The nodes of a column are distinct; at most kMaxNodesPerPoint rows.
struct NodeWeights {
  Eigen::MatrixXi nodes;    ///< K by #points
  Eigen::MatrixXd weights;  ///< K by #points
};

/// Vertex adjacency of a mesh in compressed rows, with edge lengths, for geodesic searches.
class MeshGraph {
 public:
  explicit MeshGraph(const geometry::TriangleMesh& mesh);
  /// Algorithm 1: explores the mesh from @p source in order of path length until
  /// @p count vertices for which @p is_target is true are found (the source included);
  /// returns them in the order found.
  std::vector<int> NearestTargets(int source, int count, const std::vector<int>& target_id) const;

 private:
  std::vector<int> offsets_;
  std::vector<int> adjacent_;
  std::vector<double> length_;
};

/// Samples nodes (greedy Poisson-disk over vertices in index order) and links them.
/// @pre mesh is closed and connected.
DeformationGraph BuildDeformationGraph(const geometry::TriangleMesh& mesh,
                                       const DeformationGraphOptions& options);

/// Eq. (10) weights of every mesh vertex: its vertex_neighbours nearest nodes along the
/// mesh, w_j = 1 - |v - g_j| / d_max with d_max the distance to the next node, normalised.
NodeWeights VertexWeights(const geometry::TriangleMesh& mesh, const DeformationGraph& graph,
                          const DeformationGraphOptions& options);

/// Eq. (10) weights of points that are not vertices (skeleton feature nodes): candidate
/// nodes are those acting on the points' @p support vertices; the nearest are kept.
NodeWeights PointWeights(const Eigen::Matrix3Xd& points,
                         const std::vector<std::vector<int>>& support,
                         const DeformationGraph& graph, const NodeWeights& vertex_weights,
                         int count);

}  // namespace vb::morph
