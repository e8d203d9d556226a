#include "morph/skeleton_branches.h"

#include <algorithm>
// clang-format off
// The compressed graph last, as in cloud_skeleton.cc: its boost::detail::get would hide the
// get the search uses on plain arrays.
#include <boost/graph/dijkstra_shortest_paths.hpp>
#include <boost/graph/compressed_sparse_row_graph.hpp>
// clang-format on
#include <limits>
#include <utility>
#include <vector>

namespace vb::morph {
namespace {

int NearestNode(const SkeletonGraph& skeleton, const Eigen::Vector3d& p) {
  Eigen::Index best = 0;
  (skeleton.nodes.colwise() - p).colwise().squaredNorm().minCoeff(&best);
  return static_cast<int>(best);
}

}  // namespace

std::vector<SkeletonBranch> TerminalBranches(const SkeletonGraph& skeleton,
                                             const FeatureNodes& features) {
  std::vector<SkeletonBranch> branches;
  const int n = skeleton.num_nodes();
  if (n == 0 || features.num_junctions() == 0) return branches;
  // Built once from its edge list, each undirected edge as two directed ones; each node's
  // arcs are in the order of skeleton.edges, which fixes how the search breaks ties between
  // equal paths.
  using Graph = boost::compressed_sparse_row_graph<boost::directedS, boost::no_property,
                                                   boost::property<boost::edge_weight_t, double>>;
  std::vector<std::pair<std::size_t, std::size_t>> arcs;
  std::vector<double> lengths;
  arcs.reserve(2 * skeleton.edges.size());
  lengths.reserve(2 * skeleton.edges.size());
  for (const auto& e : skeleton.edges) {
    if (e[0] == e[1]) continue;
    const auto a = static_cast<std::size_t>(e[0]), b = static_cast<std::size_t>(e[1]);
    const double length = (skeleton.nodes.col(e[0]) - skeleton.nodes.col(e[1])).norm();
    arcs.emplace_back(a, b);
    lengths.push_back(length);
    arcs.emplace_back(b, a);
    lengths.push_back(length);
  }
  const Graph graph(boost::edges_are_unsorted_multi_pass, arcs.begin(), arcs.end(), lengths.begin(),
                    static_cast<std::size_t>(n));
  std::vector<bool> is_root(static_cast<std::size_t>(n), false);
  for (Eigen::Index j = 0; j < features.junctions.cols(); ++j)
    is_root[static_cast<std::size_t>(NearestNode(skeleton, features.junctions.col(j)))] = true;

  std::vector<double> distance(static_cast<std::size_t>(n));
  std::vector<std::size_t> previous(static_cast<std::size_t>(n));
  for (Eigen::Index t = 0; t < features.terminals.cols(); ++t) {
    const int tip = NearestNode(skeleton, features.terminals.col(t));
    boost::dijkstra_shortest_paths(
        graph, static_cast<std::size_t>(tip),
        boost::predecessor_map(previous.data()).distance_map(distance.data()));
    int root = -1;
    for (int v = 0; v < n; ++v) {
      const auto s = static_cast<std::size_t>(v);
      // Dijkstra leaves nodes it cannot reach at the largest double.
      if (is_root[s] && distance[s] < std::numeric_limits<double>::max() &&
          (root < 0 || distance[s] < distance[static_cast<std::size_t>(root)]))
        root = v;
    }
    if (root < 0 || root == tip) continue;
    SkeletonBranch branch;
    branch.terminal = static_cast<int>(t);
    for (std::size_t v = static_cast<std::size_t>(root);; v = previous[v]) {
      branch.nodes.push_back(static_cast<int>(v));
      if (static_cast<int>(v) == tip || previous[v] == v) break;
    }
    // nodes run root -> tip; distances from the root
    const double total = distance[static_cast<std::size_t>(root)];
    for (int v : branch.nodes)
      branch.distance.push_back(total - distance[static_cast<std::size_t>(v)]);
    branches.push_back(std::move(branch));
  }
  return branches;
}

Eigen::Vector3d PointAlong(const SkeletonGraph& skeleton, const SkeletonBranch& branch,
                           double fraction, int* nearest_node) {
  const double s = std::clamp(fraction, 0.0, 1.0) * branch.length();
  std::size_t k = 1;
  while (k + 1 < branch.nodes.size() && branch.distance[k] < s) ++k;
  if (branch.nodes.size() < 2) {
    if (nearest_node != nullptr) *nearest_node = branch.nodes.front();
    return skeleton.nodes.col(branch.nodes.front());
  }
  const double a = branch.distance[k - 1], b = branch.distance[k];
  const double u = b > a ? std::clamp((s - a) / (b - a), 0.0, 1.0) : 1.0;
  if (nearest_node != nullptr) *nearest_node = branch.nodes[u < 0.5 ? k - 1 : k];
  return (1.0 - u) * skeleton.nodes.col(branch.nodes[k - 1]) +
         u * skeleton.nodes.col(branch.nodes[k]);
}

}  // namespace vb::morph
