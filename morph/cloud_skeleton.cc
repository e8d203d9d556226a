#include "morph/cloud_skeleton.h"

#include <algorithm>
// clang-format off
// The compressed graph last: it declares a boost::detail::get which, included before the
// others, would hide from their templates the get they use on plain arrays.
#include <boost/graph/dijkstra_shortest_paths.hpp>
#include <boost/graph/kruskal_min_spanning_tree.hpp>
#include <boost/pending/disjoint_sets.hpp>
#include <boost/graph/compressed_sparse_row_graph.hpp>
// clang-format on
#include <cmath>
#include <span>

#include "geometry/mesh_measures.h"
#include "io/error.h"
#include "morph/order_statistic.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

// The points' graph for the geodesic distances (each undirected edge as two directed ones),
// and the skeleton nodes' graph for the spanning tree (each link once): built once from an
// edge list.
using Compressed =
    boost::compressed_sparse_row_graph<boost::directedS, boost::no_property,
                                       boost::property<boost::edge_weight_t, double>>;

// An edge of the points' graph: its ends and length.
struct GraphEdge {
  int a = 0;
  int b = 0;
  double length = 0.0;
};

// The input columns each downsampled point averages: point i's are
// columns[first[i], first[i + 1]).
struct Members {
  std::vector<int> first;
  std::vector<int> columns;
  std::span<const int> operator[](int i) const {
    const auto at = static_cast<std::size_t>(i);
    return {columns.data() + first[at], static_cast<std::size_t>(first[at + 1] - first[at])};
  }
};

// Voxel-grid downsampling: one centroid per occupied cell; keeps, per output point, the
// input columns it averages.
Eigen::Matrix3Xd Downsample(const Eigen::Matrix3Xd& points, double cell, Members* members) {
  const Eigen::Vector3d lo = points.rowwise().minCoeff();
  std::vector<std::pair<std::array<std::int64_t, 3>, int>> keyed(
      static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d c = ((points.col(i) - lo) / cell).array().floor();
    keyed[static_cast<std::size_t>(i)] = {
        {static_cast<std::int64_t>(c.x()), static_cast<std::int64_t>(c.y()),
         static_cast<std::int64_t>(c.z())},
        static_cast<int>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  // At most one cell per point: reserved so that neither list grows by doubling.
  std::vector<Eigen::Vector3d> centres;
  centres.reserve(keyed.size());
  members->first.reserve(keyed.size() + 1);
  members->first.assign(1, 0);
  members->columns.resize(keyed.size());
  for (std::size_t i = 0; i < keyed.size();) {
    std::size_t j = i;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    while (j < keyed.size() && keyed[j].first == keyed[i].first) {
      sum += points.col(keyed[j].second);
      members->columns[j] = keyed[j].second;
      ++j;
    }
    members->first.push_back(static_cast<int>(j));
    centres.push_back(sum / static_cast<double>(j - i));
    i = j;
  }
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(centres.size()));
  for (std::size_t i = 0; i < centres.size(); ++i)
    out.col(static_cast<Eigen::Index>(i)) = centres[i];
  return out;
}

}  // namespace

SkeletonGraph CloudSkeleton(const Eigen::Matrix3Xd& input, const CloudSkeletonOptions& options) {
  if (input.cols() < 50)
    throw InputError("skeleton: " + std::to_string(input.cols()) + " points, fewer than 50");
  const double size = geometry::BoundingBoxDiagonal(input);
  if (!(size > 0.0)) throw InputError("skeleton: the points have no extent");

  Members members;
  Eigen::Matrix3Xd points = Downsample(input, options.voxel * size, &members);
  const int n = static_cast<int>(points.cols());
  {
    // Neighbour averaging: noise along the normals shrinks, the shape's thickness hardly.
    const PointIndex raw(points);
    std::vector<int> near;
    std::vector<double> near_d2;
    for (int round = 0; round < options.smoothing; ++round) {
      Eigen::Matrix3Xd smoothed(3, n);
      for (int i = 0; i < n; ++i) {
        raw.Nearest(points.col(i), options.neighbours + 1, &near, &near_d2);
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (int j : near) sum += points.col(j);
        smoothed.col(i) = sum / static_cast<double>(near.size());
      }
      points = smoothed;
    }
  }
  const PointIndex index(points);

  // k-nearest-neighbour graph; edges much longer than typical spacing would short-cut gaps.
  std::vector<std::array<int, 2>> edges;
  std::vector<double> lengths;
  edges.reserve(static_cast<std::size_t>(n) *
                static_cast<std::size_t>(std::max(0, options.neighbours)));
  lengths.reserve(edges.capacity());
  std::vector<int> found;
  std::vector<double> d2;
  for (int i = 0; i < n; ++i) {
    index.Nearest(points.col(i), options.neighbours + 1, &found, &d2);
    for (std::size_t k = 1; k < found.size(); ++k) {
      if (found[k] == i) continue;
      edges.push_back({std::min(i, found[k]), std::max(i, found[k])});
      lengths.push_back(std::sqrt(d2[k]));
    }
  }
  // Points on a handful of spots (duplicates, or a cloud the smoothing drew together) link
  // to nothing: no spacing to read, no shape to follow.
  if (lengths.empty())
    throw InputError("skeleton: the points sit on " + std::to_string(n) +
                     " spots that link to no other; no shape to follow");
  std::vector<double> sorted = lengths;
  const double max_edge = 3.0 * SelectUpperMedian(sorted);
  // The graph's edges in the order they are found: the short neighbour links, then the
  // bridges below. Kept as a list and made a compressed graph once complete: a graph that
  // grows keeps a vector per point, and their growth was most of a skeleton's allocations.
  std::vector<GraphEdge> graph_edges;
  graph_edges.reserve(edges.size());
  for (std::size_t e = 0; e < edges.size(); ++e)
    if (lengths[e] <= max_edge) graph_edges.push_back({edges[e][0], edges[e][1], lengths[e]});

  // Bridge pieces separated by missing regions; drop tiny pieces (outliers).
  std::vector<int> piece(static_cast<std::size_t>(n));
  int num_pieces = 0;
  {
    boost::disjoint_sets_with_storage<> linked(static_cast<std::size_t>(n));
    for (const GraphEdge& e : graph_edges) linked.union_set(e.a, e.b);
    std::vector<int> piece_of_root(static_cast<std::size_t>(n), -1);
    for (int i = 0; i < n; ++i) {
      int& p = piece_of_root[static_cast<std::size_t>(linked.find_set(i))];
      if (p < 0) p = num_pieces++;
      piece[static_cast<std::size_t>(i)] = p;
    }
  }
  std::vector<int> piece_size(static_cast<std::size_t>(num_pieces), 0);
  for (int p : piece) ++piece_size[static_cast<std::size_t>(p)];
  std::vector<bool> keep(static_cast<std::size_t>(n));
  const int min_piece = std::max(5, static_cast<int>(options.min_piece * n));
  for (int i = 0; i < n; ++i)
    keep[static_cast<std::size_t>(i)] =
        piece_size[static_cast<std::size_t>(piece[static_cast<std::size_t>(i)])] >= min_piece;
  if (std::none_of(keep.begin(), keep.end(), [](bool k) { return k; })) {
    throw InputError("skeleton: the cloud's largest linked piece has " +
                     std::to_string(*std::max_element(piece_size.begin(), piece_size.end())) +
                     " downsampled points, fewer than the " + std::to_string(min_piece) +
                     " a body needs; no body to follow");
  }
  boost::disjoint_sets_with_storage<> joined(static_cast<std::size_t>(num_pieces));
  auto group_of = [&](int i) {
    return static_cast<int>(joined.find_set(piece[static_cast<std::size_t>(i)]));
  };
  for (bool merged = true; merged;) {
    merged = false;
    // Closest pair between the group of the first kept point and everything else kept.
    int first = -1;
    for (int i = 0; i < n && first < 0; ++i) first = keep[static_cast<std::size_t>(i)] ? i : -1;
    if (first < 0) break;
    const int group = group_of(first);
    double best = std::numeric_limits<double>::infinity();
    std::array<int, 2> pair{-1, -1};
    for (int i = 0; i < n; ++i) {
      if (!keep[static_cast<std::size_t>(i)] || group_of(i) == group) continue;
      index.Nearest(points.col(i), 48, &found, &d2);
      for (std::size_t k = 0; k < found.size(); ++k) {
        const int j = found[k];
        if (keep[static_cast<std::size_t>(j)] && group_of(j) == group && d2[k] < best) {
          best = d2[k];
          pair = {i, j};
        }
      }
    }
    if (pair[0] < 0) {
      // No piece within reach of the kd-query: every other kept point's nearest in the group,
      // from a kd-tree of the group (n log n; a search over every pair is n squared).
      std::vector<int> members;
      for (int j = 0; j < n; ++j)
        if (keep[static_cast<std::size_t>(j)] && group_of(j) == group) members.push_back(j);
      const Eigen::Matrix3Xd member_points = points(Eigen::all, members);
      const PointIndex member_index(member_points);
      for (int i = 0; i < n; ++i) {
        if (!keep[static_cast<std::size_t>(i)] || group_of(i) == group) continue;
        const int j = members[static_cast<std::size_t>(member_index.Nearest(points.col(i)))];
        const double dd = (points.col(i) - points.col(j)).squaredNorm();
        if (dd < best) {
          best = dd;
          pair = {i, j};
        }
      }
    }
    if (pair[0] >= 0) {
      graph_edges.push_back({pair[0], pair[1], std::sqrt(best)});
      joined.union_set(piece[static_cast<std::size_t>(pair[0])], group);
      merged = true;
    }
  }

  // Geodesic distance from an extremity, over both directions of every edge; each point's
  // edges in the order they were found.
  std::vector<std::pair<int, int>> directed;
  std::vector<double> directed_length;
  directed.reserve(2 * graph_edges.size());
  directed_length.reserve(2 * graph_edges.size());
  for (const GraphEdge& e : graph_edges) {
    directed.emplace_back(e.a, e.b);
    directed.emplace_back(e.b, e.a);
    directed_length.push_back(e.length);
    directed_length.push_back(e.length);
  }
  const Compressed graph(boost::edges_are_unsorted_multi_pass, directed.begin(), directed.end(),
                         directed_length.begin(), static_cast<std::size_t>(n));
  std::vector<double> distance(static_cast<std::size_t>(n));
  auto geodesic_from = [&](int source) {
    boost::dijkstra_shortest_paths(graph, static_cast<std::size_t>(source),
                                   boost::distance_map(distance.data()));
  };
  int start = 0;
  while (!keep[static_cast<std::size_t>(start)]) ++start;
  geodesic_from(start);
  int root = start;
  for (int i = 0; i < n; ++i) {
    if (keep[static_cast<std::size_t>(i)] && std::isfinite(distance[static_cast<std::size_t>(i)]) &&
        distance[static_cast<std::size_t>(i)] > distance[static_cast<std::size_t>(root)]) {
      root = i;
    }
  }
  geodesic_from(root);

  // Pieces of each distance band.
  const double band = options.band * size;
  std::vector<int> band_of(static_cast<std::size_t>(n), -1);
  for (int i = 0; i < n; ++i) {
    if (keep[static_cast<std::size_t>(i)] && std::isfinite(distance[static_cast<std::size_t>(i)])) {
      band_of[static_cast<std::size_t>(i)] =
          static_cast<int>(distance[static_cast<std::size_t>(i)] / band);
    }
  }
  boost::disjoint_sets_with_storage<> pieces(static_cast<std::size_t>(n));
  auto piece_of = [&](int i) { return static_cast<int>(pieces.find_set(i)); };
  for (const auto& [a, b, unused] : graph_edges) {
    if (band_of[static_cast<std::size_t>(a)] >= 0 &&
        band_of[static_cast<std::size_t>(a)] == band_of[static_cast<std::size_t>(b)]) {
      pieces.union_set(a, b);
    }
  }
  // A band is only a few samples thick, so a ring around a limb can fall apart into arcs
  // that touch only through the neighbouring bands; join same-band samples closer than
  // half a band. (Pieces of one band on different limbs are farther apart than that.)
  for (int i = 0; i < n; ++i) {
    if (band_of[static_cast<std::size_t>(i)] < 0) continue;
    index.Nearest(points.col(i), 2 * options.neighbours, &found, &d2);
    for (std::size_t k = 1; k < found.size(); ++k) {
      if (band_of[static_cast<std::size_t>(found[k])] == band_of[static_cast<std::size_t>(i)] &&
          d2[k] < 0.25 * band * band) {
        pieces.union_set(i, found[k]);
      }
    }
  }
  // Fold noise-sized pieces into the neighbouring piece of their band they share the most
  // graph edges with (the lowest-numbered one on a tie).
  {
    // Points of each piece, at its root.
    std::vector<int> piece_points(static_cast<std::size_t>(n), 0);
    for (int i = 0; i < n; ++i) {
      if (band_of[static_cast<std::size_t>(i)] >= 0)
        ++piece_points[static_cast<std::size_t>(piece_of(i))];
    }
    std::vector<int> sizes;
    for (const int count : piece_points) {
      if (count > 0) sizes.push_back(count);
    }
    if (!sizes.empty()) {
      const double small = options.min_band_piece * SelectUpperMedian(sizes);
      const auto points_of = [&](int root) { return piece_points[static_cast<std::size_t>(root)]; };
      // Each graph edge between two pieces side by side in one band, both ways round as
      // (piece, neighbour); sorted, a run of equal pairs counts the edges they share. Pieces
      // of neighbouring bands are left out: a limb's last, small band piece continues a chain
      // from the band before and must stay a tip.
      std::vector<std::pair<int, int>> touching;
      for (const auto& [a, b, unused] : graph_edges) {
        if (band_of[static_cast<std::size_t>(a)] < 0 ||
            band_of[static_cast<std::size_t>(a)] != band_of[static_cast<std::size_t>(b)])
          continue;
        const int ra = piece_of(a), rb = piece_of(b);
        if (ra == rb) continue;
        touching.emplace_back(ra, rb);
        touching.emplace_back(rb, ra);
      }
      std::sort(touching.begin(), touching.end());
      for (std::size_t at = 0; at < touching.size();) {
        const int root = touching[at].first;
        int best = -1, best_edges = 0;
        for (; at < touching.size() && touching[at].first == root;) {
          std::size_t end = at + 1;
          while (end < touching.size() && touching[end] == touching[at]) ++end;
          const int other = touching[at].second;
          const int edges = static_cast<int>(end - at);
          if (edges > best_edges && points_of(other) >= small) {
            best = other;
            best_edges = edges;
          }
          at = end;
        }
        if (points_of(root) < small && best >= 0) pieces.union_set(root, best);
      }
    }
  }
  // One skeleton node per piece, numbered in the order of the pieces' first points.
  std::vector<int> node_of_root(static_cast<std::size_t>(n), -1);
  std::vector<int> node_of(static_cast<std::size_t>(n), -1);
  std::vector<std::size_t> support_size;
  for (int i = 0; i < n; ++i) {
    if (band_of[static_cast<std::size_t>(i)] < 0) continue;
    int& node = node_of_root[static_cast<std::size_t>(piece_of(i))];
    if (node < 0) {
      node = static_cast<int>(support_size.size());
      support_size.push_back(0);
    }
    node_of[static_cast<std::size_t>(i)] = node;
    support_size[static_cast<std::size_t>(node)] += members[i].size();
  }
  SkeletonGraph skeleton;
  std::vector<Eigen::Vector3d> sums(support_size.size(), Eigen::Vector3d::Zero());
  skeleton.support.resize(support_size.size());
  for (std::size_t v = 0; v < support_size.size(); ++v)
    skeleton.support[v].reserve(support_size[v]);
  for (int i = 0; i < n; ++i) {
    const int node = node_of[static_cast<std::size_t>(i)];
    if (node < 0) continue;
    const std::span<const int> averaged = members[i];
    sums[static_cast<std::size_t>(node)] += points.col(i) * static_cast<double>(averaged.size());
    auto& support = skeleton.support[static_cast<std::size_t>(node)];
    support.insert(support.end(), averaged.begin(), averaged.end());
  }
  skeleton.nodes.resize(3, static_cast<Eigen::Index>(sums.size()));
  for (std::size_t v = 0; v < sums.size(); ++v) {
    skeleton.nodes.col(static_cast<Eigen::Index>(v)) =
        sums[v] / static_cast<double>(skeleton.support[v].size());
  }

  // Join pieces that touch across neighbouring bands, then keep a minimum spanning tree.
  std::vector<std::pair<int, int>> links;
  for (const auto& [a, b, unused] : graph_edges) {
    const int na = node_of[static_cast<std::size_t>(a)], nb = node_of[static_cast<std::size_t>(b)];
    if (na < 0 || nb < 0 || na == nb) continue;
    links.emplace_back(std::min(na, nb), std::max(na, nb));
  }
  std::sort(links.begin(), links.end());
  links.erase(std::unique(links.begin(), links.end()), links.end());
  // Each link once, from its lower node, in the sorted order: the spanning tree reads only
  // the edge list, and a compressed graph is built in a few arrays where a graph grown edge by
  // edge keeps a list per node.
  std::vector<double> link_lengths;
  link_lengths.reserve(links.size());
  for (const auto& [a, b] : links)
    link_lengths.push_back((skeleton.nodes.col(a) - skeleton.nodes.col(b)).norm());
  const Compressed nodes_graph(boost::edges_are_sorted, links.begin(), links.end(),
                               link_lengths.begin(), sums.size());
  std::vector<Compressed::edge_descriptor> tree;
  tree.reserve(sums.size());
  boost::kruskal_minimum_spanning_tree(nodes_graph, std::back_inserter(tree));
  for (const auto& e : tree) {
    skeleton.edges.push_back({static_cast<int>(boost::source(e, nodes_graph)),
                              static_cast<int>(boost::target(e, nodes_graph))});
  }
  return skeleton;
}

}  // namespace vb::morph
