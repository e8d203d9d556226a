#include "morph/deformation_graph.h"

#include <algorithm>
#include <boost/graph/adjacency_list.hpp>
#include <boost/graph/biconnected_components.hpp>
#include <cmath>
#include <limits>
#include <queue>
#include <set>
#include <unordered_map>
#include <unordered_set>

#include "geometry/mesh_measures.h"
#include "io/error.h"

namespace vb::morph {

MeshGraph::MeshGraph(const geometry::TriangleMesh& mesh) {
  std::vector<std::pair<int, int>> directed;
  directed.reserve(static_cast<std::size_t>(6 * mesh.num_faces()));
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.F(k, f), b = mesh.F((k + 1) % 3, f);
      directed.emplace_back(a, b);
      directed.emplace_back(b, a);
    }
  }
  std::sort(directed.begin(), directed.end());
  directed.erase(std::unique(directed.begin(), directed.end()), directed.end());
  offsets_.assign(static_cast<std::size_t>(mesh.num_vertices()) + 1, 0);
  for (const auto& [a, b] : directed) ++offsets_[static_cast<std::size_t>(a) + 1];
  for (std::size_t i = 1; i < offsets_.size(); ++i) offsets_[i] += offsets_[i - 1];
  for (const auto& [a, b] : directed) {
    adjacent_.push_back(b);
    length_.push_back((mesh.V.col(a) - mesh.V.col(b)).norm());
  }
}

std::vector<int> MeshGraph::NearestTargets(int source, int count,
                                           const std::vector<int>& target_id) const {
  // Dijkstra with early exit and a sparse distance map: it touches only the few hundred
  // vertices around the source (Boost's Dijkstra can stop early only by throwing).
  std::vector<int> found;
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  std::unordered_map<int, double> best;
  best[source] = 0.0;
  queue.push({0.0, source});
  std::unordered_set<int> done;
  while (!queue.empty() && static_cast<int>(found.size()) < count) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (!done.insert(v).second) continue;
    if (target_id[static_cast<std::size_t>(v)] >= 0) found.push_back(v);
    for (int e = offsets_[static_cast<std::size_t>(v)];
         e < offsets_[static_cast<std::size_t>(v) + 1]; ++e) {
      const int u = adjacent_[static_cast<std::size_t>(e)];
      const double du = d + length_[static_cast<std::size_t>(e)];
      auto it = best.find(u);
      if (it == best.end() || du < it->second) {
        best[u] = du;
        queue.push({du, u});
      }
    }
  }
  return found;
}

DeformationGraph BuildDeformationGraph(const geometry::TriangleMesh& mesh,
                                       const DeformationGraphOptions& options) {
  const double size = geometry::BoundingBoxDiagonal(mesh.V);
  const double spacing = options.node_spacing * size;
  DeformationGraph g;
  // Greedy Poisson-disk sampling on a hash grid of cell = spacing.
  std::unordered_map<std::int64_t, std::vector<int>> grid;
  const Eigen::Vector3d lo = mesh.V.rowwise().minCoeff();
  auto cell_of = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3i c = ((p - lo) / spacing).array().floor().cast<int>();
    return c;
  };
  auto key = [](const Eigen::Vector3i& c) {
    return (static_cast<std::int64_t>(c.x()) * 73856093) ^
           (static_cast<std::int64_t>(c.y()) * 19349663) ^
           (static_cast<std::int64_t>(c.z()) * 83492791);
  };
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3i c = cell_of(mesh.V.col(v));
    bool free = true;
    for (int dx = -1; dx <= 1 && free; ++dx) {
      for (int dy = -1; dy <= 1 && free; ++dy) {
        for (int dz = -1; dz <= 1 && free; ++dz) {
          auto it = grid.find(key(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == grid.end()) continue;
          for (int node : it->second) {
            if ((mesh.V.col(g.node_vertex[static_cast<std::size_t>(node)]) - mesh.V.col(v)).norm() <
                spacing) {
              free = false;
              break;
            }
          }
        }
      }
    }
    if (free) {
      grid[key(c)].push_back(static_cast<int>(g.node_vertex.size()));
      g.node_vertex.push_back(v);
    }
  }
  g.nodes.resize(3, static_cast<Eigen::Index>(g.node_vertex.size()));
  for (std::size_t j = 0; j < g.node_vertex.size(); ++j)
    g.nodes.col(static_cast<Eigen::Index>(j)) = mesh.V.col(g.node_vertex[j]);

  // Edges: each node to its mu nearest nodes along the mesh (Algorithm 1).
  std::vector<int> node_of_vertex(static_cast<std::size_t>(mesh.num_vertices()), -1);
  for (std::size_t j = 0; j < g.node_vertex.size(); ++j)
    node_of_vertex[static_cast<std::size_t>(g.node_vertex[j])] = static_cast<int>(j);
  const MeshGraph mesh_graph(mesh);
  std::set<std::array<int, 2>> edge_set;
  g.neighbours.resize(g.node_vertex.size());
  for (int j = 0; j < g.num_nodes(); ++j) {
    const std::vector<int> found = mesh_graph.NearestTargets(
        g.node_vertex[static_cast<std::size_t>(j)], options.graph_neighbours + 1, node_of_vertex);
    for (int v : found) {
      const int k = node_of_vertex[static_cast<std::size_t>(v)];
      if (k == j) continue;
      g.neighbours[static_cast<std::size_t>(j)].push_back(k);
      edge_set.insert({std::min(j, k), std::max(j, k)});
    }
  }
  g.edges.assign(edge_set.begin(), edge_set.end());

  // Bridges: biconnected components holding a single edge (found by DFS).
  using Graph =
      boost::adjacency_list<boost::vecS, boost::vecS, boost::undirectedS, boost::no_property,
                            boost::property<boost::edge_index_t, std::size_t>>;
  Graph bg(static_cast<std::size_t>(g.num_nodes()));
  for (std::size_t e = 0; e < g.edges.size(); ++e) {
    boost::add_edge(static_cast<std::size_t>(g.edges[e][0]),
                    static_cast<std::size_t>(g.edges[e][1]), e, bg);
  }
  std::vector<std::size_t> component(g.edges.size());
  const auto edge_index = boost::get(boost::edge_index, bg);
  const std::size_t num_components = boost::biconnected_components(
      bg, boost::make_iterator_property_map(component.begin(), edge_index));
  std::vector<int> edges_in(num_components, 0);
  for (std::size_t c : component) ++edges_in[c];
  for (std::size_t e = 0; e < g.edges.size(); ++e) {
    if (edges_in[component[e]] == 1) g.bridges.push_back(g.edges[e]);
  }
  return g;
}

namespace {

// Eq. (10) from candidate nodes: the `count` nearest get weights. @p candidate_list is
// made unique and sorted nearest first, in place.
void FillWeights(const Eigen::Vector3d& p, std::vector<int>* candidate_list,
                 const DeformationGraph& graph, int count, Eigen::Index column, NodeWeights* out) {
  std::vector<int>& candidates = *candidate_list;
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  std::sort(candidates.begin(), candidates.end(), [&](int a, int b) {
    return (graph.nodes.col(a) - p).squaredNorm() < (graph.nodes.col(b) - p).squaredNorm();
  });
  const int used = std::min<int>(count, static_cast<int>(candidates.size()));
  VB_DEMAND(used > 0);
  // d_max: distance to the next node after the used ones (or a little past the last).
  const double d_max =
      static_cast<int>(candidates.size()) > used
          ? (graph.nodes.col(candidates[static_cast<std::size_t>(used)]) - p).norm()
          : 1.05 * (graph.nodes.col(candidates[static_cast<std::size_t>(used - 1)]) - p).norm() +
                1e-12;
  double total = 0.0;
  for (int k = 0; k < used; ++k) {
    const double w = std::max(
        0.0, 1.0 - (graph.nodes.col(candidates[static_cast<std::size_t>(k)]) - p).norm() / d_max);
    out->nodes(k, column) = candidates[static_cast<std::size_t>(k)];
    out->weights(k, column) = w;
    total += w;
  }
  if (total <= 0.0) {  // the point sits at d_max from all: share equally
    for (int k = 0; k < used; ++k) out->weights(k, column) = 1.0 / used;
  } else {
    out->weights.col(column).head(used) /= total;
  }
}

}  // namespace

NodeWeights VertexWeights(const geometry::TriangleMesh& mesh, const DeformationGraph& graph,
                          const DeformationGraphOptions& options) {
  std::vector<int> node_of_vertex(static_cast<std::size_t>(mesh.num_vertices()), -1);
  for (std::size_t j = 0; j < graph.node_vertex.size(); ++j)
    node_of_vertex[static_cast<std::size_t>(graph.node_vertex[j])] = static_cast<int>(j);
  const MeshGraph mesh_graph(mesh);
  const int k = options.vertex_neighbours;
  NodeWeights w;
  w.nodes = Eigen::MatrixXi::Constant(k, mesh.num_vertices(), -1);
  w.weights = Eigen::MatrixXd::Zero(k, mesh.num_vertices());
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    std::vector<int> nodes;
    for (int u : mesh_graph.NearestTargets(v, k + 1, node_of_vertex))
      nodes.push_back(node_of_vertex[static_cast<std::size_t>(u)]);
    FillWeights(mesh.V.col(v), &nodes, graph, k, v, &w);
  }
  return w;
}

NodeWeights PointWeights(const Eigen::Matrix3Xd& points,
                         const std::vector<std::vector<int>>& support,
                         const DeformationGraph& graph, const NodeWeights& vertex_weights,
                         int count) {
  NodeWeights w;
  w.nodes = Eigen::MatrixXi::Constant(count, points.cols(), -1);
  w.weights = Eigen::MatrixXd::Zero(count, points.cols());
  std::vector<int> candidates;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    candidates.clear();
    if (static_cast<std::size_t>(i) < support.size()) {
      for (int v : support[static_cast<std::size_t>(i)]) {
        for (Eigen::Index k = 0; k < vertex_weights.nodes.rows(); ++k) {
          if (vertex_weights.nodes(k, v) >= 0) candidates.push_back(vertex_weights.nodes(k, v));
        }
      }
    }
    if (candidates.empty()) {  // no support: the Euclidean nearest nodes
      for (int j = 0; j < graph.num_nodes(); ++j) candidates.push_back(j);
    }
    FillWeights(points.col(i), &candidates, graph, count, i, &w);
  }
  return w;
}

}  // namespace vb::morph
