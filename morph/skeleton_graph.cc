#include "morph/skeleton_graph.h"

#include <algorithm>
#include <boost/pending/disjoint_sets.hpp>
#include <cmath>
#include <limits>
#include <queue>
#include <span>
#include <utility>
#include <vector>

namespace vb::morph {

std::vector<int> SkeletonGraph::Degrees() const {
  std::vector<int> degree(static_cast<std::size_t>(num_nodes()), 0);
  for (const auto& e : edges) {
    ++degree[static_cast<std::size_t>(e[0])];
    ++degree[static_cast<std::size_t>(e[1])];
  }
  return degree;
}

namespace {

// Each node's neighbours with the edges' lengths, in the edges' order, in one array: node v's
// are next_[first_[v], first_[v + 1]).
class Adjacency {
 public:
  explicit Adjacency(const SkeletonGraph& g)
      : first_(static_cast<std::size_t>(g.num_nodes()) + 1, 0) {
    for (const auto& e : g.edges) {
      if (e[0] == e[1]) continue;
      ++first_[static_cast<std::size_t>(e[0]) + 1];
      ++first_[static_cast<std::size_t>(e[1]) + 1];
    }
    for (std::size_t v = 1; v < first_.size(); ++v) first_[v] += first_[v - 1];
    next_.resize(first_.back());
    std::vector<std::size_t> at(first_.begin(), first_.end() - 1);
    for (const auto& e : g.edges) {
      if (e[0] == e[1]) continue;
      const double length = (g.nodes.col(e[0]) - g.nodes.col(e[1])).norm();
      next_[at[static_cast<std::size_t>(e[0])]++] = {e[1], length};
      next_[at[static_cast<std::size_t>(e[1])]++] = {e[0], length};
    }
  }
  // (neighbour, length) of node @p v.
  std::span<const std::pair<int, double>> next(int v) const {
    const auto at = static_cast<std::size_t>(v);
    return {next_.data() + first_[at], first_[at + 1] - first_[at]};
  }
  int degree(int v, const std::vector<bool>& alive) const {
    int d = 0;
    for (const auto& [u, length] : next(v)) d += alive[static_cast<std::size_t>(u)] ? 1 : 0;
    return d;
  }

 private:
  std::vector<std::size_t> first_;
  std::vector<std::pair<int, double>> next_;
};

}  // namespace

FeatureNodes ExtractFeatureNodes(const SkeletonGraph& skeleton, const FeatureOptions& options) {
  const int n = skeleton.num_nodes();
  const Adjacency adjacency(skeleton);
  std::vector<bool> alive(static_cast<std::size_t>(n), true);

  // Prune: walk from each terminal to the first node of degree >= 3; if that branch is
  // short, remove it (not the junction). Repeat until nothing changes, shortest first.
  std::vector<int> branch, shortest_branch;  // reused from walk to walk
  for (bool changed = true; changed;) {
    changed = false;
    double shortest = options.min_branch_length;
    shortest_branch.clear();
    for (int t = 0; t < n; ++t) {
      if (!alive[static_cast<std::size_t>(t)] || adjacency.degree(t, alive) != 1) continue;
      branch.assign(1, t);
      double length = 0.0;
      int previous = -1, current = t;
      while (true) {
        int step = -1;
        double step_length = 0.0;
        for (const auto& [u, l] : adjacency.next(current)) {
          if (alive[static_cast<std::size_t>(u)] && u != previous) {
            step = u;
            step_length = l;
            break;
          }
        }
        if (step < 0) {
          length = std::numeric_limits<double>::infinity();  // an isolated chain: keep it
          break;
        }
        length += step_length;
        if (adjacency.degree(step, alive) >= 3) break;
        if (adjacency.degree(step, alive) == 1) {
          length = std::numeric_limits<double>::infinity();
          break;
        }
        branch.push_back(step);
        previous = current;
        current = step;
      }
      if (length < shortest) {
        shortest = length;
        shortest_branch = branch;
      }
    }
    if (!shortest_branch.empty()) {
      for (int v : shortest_branch) alive[static_cast<std::size_t>(v)] = false;
      changed = true;
    }
  }

  // Junctions within the merge distance along the skeleton become one.
  std::vector<int> junctions, terminals;
  for (int v = 0; v < n; ++v) {
    if (!alive[static_cast<std::size_t>(v)]) continue;
    const int d = adjacency.degree(v, alive);
    if (d == 1) terminals.push_back(v);
    if (d >= 3) junctions.push_back(v);
  }
  boost::disjoint_sets_with_storage<> group(junctions.size());
  // Reused from junction to junction (each search leaves the queue empty).
  std::vector<double> distance;
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  for (std::size_t a = 0; a < junctions.size(); ++a) {
    // Bounded Dijkstra from junction a over the living skeleton.
    distance.assign(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
    distance[static_cast<std::size_t>(junctions[a])] = 0.0;
    queue.push({0.0, junctions[a]});
    while (!queue.empty()) {
      const auto [d, v] = queue.top();
      queue.pop();
      if (d > distance[static_cast<std::size_t>(v)] || d > options.junction_merge_distance)
        continue;
      for (const auto& [u, l] : adjacency.next(v)) {
        if (!alive[static_cast<std::size_t>(u)] || d + l >= distance[static_cast<std::size_t>(u)])
          continue;
        distance[static_cast<std::size_t>(u)] = d + l;
        queue.push({d + l, u});
      }
    }
    for (std::size_t b = a + 1; b < junctions.size(); ++b) {
      if (distance[static_cast<std::size_t>(junctions[b])] <= options.junction_merge_distance) {
        group.union_set(a, b);
      }
    }
  }

  FeatureNodes features;
  auto support_of = [&](int v) {
    return static_cast<std::size_t>(v) < skeleton.support.size()
               ? skeleton.support[static_cast<std::size_t>(v)]
               : std::vector<int>{};
  };
  features.terminals.resize(3, static_cast<Eigen::Index>(terminals.size()));
  for (std::size_t i = 0; i < terminals.size(); ++i) {
    features.terminals.col(static_cast<Eigen::Index>(i)) = skeleton.nodes.col(terminals[i]);
    features.terminal_support.push_back(support_of(terminals[i]));
  }
  std::vector<Eigen::Vector3d> merged_position;
  std::vector<std::vector<int>> merged_support;
  std::vector<int> merged_count;
  std::vector<int> slot(junctions.size(), -1);
  for (std::size_t j = 0; j < junctions.size(); ++j) {
    const auto root = static_cast<std::size_t>(group.find_set(j));
    if (slot[root] < 0) {
      slot[root] = static_cast<int>(merged_position.size());
      merged_position.emplace_back(Eigen::Vector3d::Zero());
      merged_support.emplace_back();
      merged_count.push_back(0);
    }
    const auto s = static_cast<std::size_t>(slot[root]);
    merged_position[s] += skeleton.nodes.col(junctions[j]);
    ++merged_count[s];
    const auto support = support_of(junctions[j]);
    merged_support[s].insert(merged_support[s].end(), support.begin(), support.end());
  }
  features.junctions.resize(3, static_cast<Eigen::Index>(merged_position.size()));
  for (std::size_t s = 0; s < merged_position.size(); ++s) {
    features.junctions.col(static_cast<Eigen::Index>(s)) = merged_position[s] / merged_count[s];
  }
  features.junction_support = std::move(merged_support);
  return features;
}

}  // namespace vb::morph
