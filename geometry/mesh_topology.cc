#include "geometry/mesh_topology.h"

#include <algorithm>
#include <array>
#include <boost/iterator/counting_iterator.hpp>
#include <boost/pending/disjoint_sets.hpp>
#include <vector>

#include "io/error.h"

namespace vb::geometry {
namespace {

struct HalfEdge {
  int lo, hi;  // undirected key
  int face;
  bool forward;  // traversed lo -> hi
  bool operator<(const HalfEdge& o) const {
    return std::tie(lo, hi, face) < std::tie(o.lo, o.hi, o.face);
  }
};

}  // namespace

int TopologyReport::genus() const {
  VB_DEMAND(is_single_closed_surface());
  return (2 - euler_characteristic()) / 2;
}

std::string TopologyReport::Describe() const {
  std::string s =
      std::to_string(num_vertices) + " vertices, " + std::to_string(num_faces) + " faces";
  auto add = [&s](int count, const char* what) {
    if (count > 0) s += ", " + std::to_string(count) + " " + what;
  };
  add(boundary_edges, "boundary edges");
  add(nonmanifold_edges, "non-manifold edges");
  add(inconsistent_edges, "inconsistently oriented edges");
  add(degenerate_faces, "degenerate faces");
  add(unreferenced_vertices, "unreferenced vertices");
  add(nonmanifold_vertices, "non-manifold vertices");
  s += ", " + std::to_string(components) + " component(s), Euler characteristic " +
       std::to_string(euler_characteristic());
  return s;
}

VertexFaces::VertexFaces(const TriangleMesh& mesh)
    : first_(static_cast<std::size_t>(mesh.num_vertices()) + 1, 0),
      faces_(static_cast<std::size_t>(3 * mesh.F.cols())) {
  for (Eigen::Index f = 0; f < mesh.F.cols(); ++f)
    for (Eigen::Index k = 0; k < 3; ++k) ++first_[static_cast<std::size_t>(mesh.F(k, f)) + 1];
  for (std::size_t v = 1; v < first_.size(); ++v) first_[v] += first_[v - 1];
  std::vector<int> filled(first_.begin(), first_.end() - 1);  // next free slot per vertex
  for (Eigen::Index f = 0; f < mesh.F.cols(); ++f)
    for (Eigen::Index k = 0; k < 3; ++k)
      faces_[static_cast<std::size_t>(filled[static_cast<std::size_t>(mesh.F(k, f))]++)] =
          static_cast<int>(f);
}

TopologyReport AnalyzeTopology(const TriangleMesh& mesh) {
  TopologyReport r;
  r.num_vertices = mesh.num_vertices();
  r.num_faces = mesh.num_faces();
  std::vector<HalfEdge> half_edges;
  half_edges.reserve(static_cast<std::size_t>(3 * r.num_faces));
  std::vector<int> uses(static_cast<std::size_t>(r.num_vertices), 0);
  for (int f = 0; f < r.num_faces; ++f) {
    const std::array<int, 3> v = {mesh.F(0, f), mesh.F(1, f), mesh.F(2, f)};
    for (int k = 0; k < 3; ++k) {
      VB_DEMAND(v[k] >= 0 && v[k] < r.num_vertices);
      ++uses[static_cast<std::size_t>(v[k])];
    }
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0]) {
      ++r.degenerate_faces;
      continue;
    }
    for (int k = 0; k < 3; ++k) {
      const int a = v[k], b = v[(k + 1) % 3];
      half_edges.push_back({std::min(a, b), std::max(a, b), f, a < b});
    }
  }
  r.unreferenced_vertices = static_cast<int>(std::count(uses.begin(), uses.end(), 0));
  std::sort(half_edges.begin(), half_edges.end());

  boost::disjoint_sets_with_storage<> components(static_cast<std::size_t>(r.num_faces));
  // Per vertex, faces that meet along an edge through that vertex belong to one fan.
  std::vector<std::pair<int, std::array<int, 2>>> vertex_links;  // (vertex, {face, face})
  vertex_links.reserve(half_edges.size() * 2);
  for (std::size_t i = 0; i < half_edges.size();) {
    std::size_t j = i;
    while (j < half_edges.size() && half_edges[j].lo == half_edges[i].lo &&
           half_edges[j].hi == half_edges[i].hi)
      ++j;
    ++r.num_edges;
    const std::size_t count = j - i;
    if (count == 1) {
      ++r.boundary_edges;
    } else if (count > 2) {
      ++r.nonmanifold_edges;
    } else if (half_edges[i].forward == half_edges[i + 1].forward) {
      ++r.inconsistent_edges;
    }
    for (std::size_t k = i + 1; k < j; ++k) {
      components.union_set(half_edges[i].face, half_edges[k].face);
      if (count == 2) {
        vertex_links.push_back({half_edges[i].lo, {half_edges[i].face, half_edges[k].face}});
        vertex_links.push_back({half_edges[i].hi, {half_edges[i].face, half_edges[k].face}});
      }
    }
    i = j;
  }
  r.components = static_cast<int>(components.count_sets(
      boost::counting_iterator<int>(0), boost::counting_iterator<int>(r.num_faces)));

  // A vertex is manifold when its incident faces, linked through shared edges at the vertex,
  // form one group. Count groups per vertex with a union-find over face slots.
  const VertexFaces faces_of_vertex(mesh);
  std::sort(vertex_links.begin(), vertex_links.end());
  std::size_t link = 0;
  for (int v = 0; v < r.num_vertices; ++v) {
    const std::span<const int> faces = faces_of_vertex[v];
    if (faces.empty()) continue;
    boost::disjoint_sets_with_storage<> fan(faces.size());
    auto slot = [&faces](int face) {
      return static_cast<int>(std::lower_bound(faces.begin(), faces.end(), face) - faces.begin());
    };
    for (; link < vertex_links.size() && vertex_links[link].first == v; ++link) {
      fan.union_set(slot(vertex_links[link].second[0]), slot(vertex_links[link].second[1]));
    }
    const auto fans = fan.count_sets(boost::counting_iterator<std::size_t>(0),
                                     boost::counting_iterator<std::size_t>(faces.size()));
    if (fans > 1) ++r.nonmanifold_vertices;
  }
  return r;
}

}  // namespace vb::geometry
