#pragma once

#include <span>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"

namespace vb::geometry {

/// What a mesh's connectivity is, as counts; built by AnalyzeTopology.
struct TopologyReport {
  int num_vertices = 0;
  int num_faces = 0;
  int num_edges = 0;
  int boundary_edges = 0;         ///< edges with one incident face
  int nonmanifold_edges = 0;      ///< edges with three or more incident faces
  int inconsistent_edges = 0;     ///< two-face edges both faces traverse the same way
  int degenerate_faces = 0;       ///< faces that repeat a vertex index
  int unreferenced_vertices = 0;  ///< vertices no face uses
  int nonmanifold_vertices = 0;   ///< vertices whose incident faces form more than one fan
  int components = 0;             ///< face-connected components

  int euler_characteristic() const { return num_vertices - num_edges + num_faces; }
  /// Handles of a single closed, oriented surface: (2 - Euler characteristic) / 2, 0 for a
  /// sphere, 1 for a torus. @pre is_single_closed_surface().
  int genus() const;
  /// Closed (watertight) and 2-manifold, no degenerate faces or loose vertices.
  bool is_closed_manifold() const {
    return boundary_edges == 0 && nonmanifold_edges == 0 && degenerate_faces == 0 &&
           unreferenced_vertices == 0 && nonmanifold_vertices == 0 && num_faces > 0;
  }
  /// Every interior edge is traversed in opposite directions by its two faces.
  bool is_consistently_oriented() const {
    return inconsistent_edges == 0 && nonmanifold_edges == 0;
  }
  /// What a template must be: one closed, consistently oriented 2-manifold.
  bool is_single_closed_surface() const {
    return is_closed_manifold() && is_consistently_oriented() && components == 1;
  }
  /// One line naming every defect, for error messages.
  std::string Describe() const;
};

/// The faces round each vertex of a mesh, in increasing order, all in one array (compressed
/// rows: three allocations for the whole mesh).
class VertexFaces {
 public:
  /// @pre every index in mesh.F is in [0, #V).
  explicit VertexFaces(const TriangleMesh& mesh);
  /// The faces round vertex @p v. @pre 0 <= v < the mesh's vertex count.
  std::span<const int> operator[](int v) const {
    const auto at = static_cast<std::size_t>(v);
    return {faces_.data() + first_[at], static_cast<std::size_t>(first_[at + 1] - first_[at])};
  }

 private:
  std::vector<int> first_;  // vertex v's faces are faces_[first_[v], first_[v + 1])
  std::vector<int> faces_;
};

/// Counts boundary, non-manifold and inconsistently oriented edges, loose vertices, vertex
/// fans and components of @p mesh. O(F log F).
/// @pre every index in mesh.F is in [0, #V).
TopologyReport AnalyzeTopology(const TriangleMesh& mesh);

}  // namespace vb::geometry
