#pragma once

#include <Eigen/Core>
#include <vector>

#include "geometry/triangle_mesh.h"

namespace vb::tools {

/// Lengths are fractions of the input's bounding-box diagonal.
struct WrapOptions {
  /// CGAL's alpha: gaps narrower than about this are bridged, details finer are smoothed.
  double alpha = 0.01;
  /// How far outside the input the wrap lies.
  double offset = 0.0014;
};

/// A closed, 2-manifold, outward-oriented surface around any triangle soup (open, several
/// components, self-intersecting): CGAL's 3D alpha wrapping.
/// @param[in] soup  triangles; its normals are ignored.
/// @throws InputError when the soup has no non-degenerate triangle or the wrap is empty.
geometry::TriangleMesh WrapSurface(const geometry::TriangleMesh& soup,
                                   const WrapOptions& options = {});

/// Where a point sits relative to a triangle soup: its closest triangle, the closest point's
/// barycentric coordinates in it, and the offset from that point in the triangle's own frame
/// (along the first edge, across it in the plane, along the normal).
struct SurfaceAnchor {
  int face = 0;  ///< column of the surface's F
  /// Weights of the face's three corners, in F's order; they sum to 1.
  Eigen::Vector3d barycentric = Eigen::Vector3d::Zero();
  /// From the closest point to the anchored point, in the surface's units, along (first edge,
  /// in-plane perpendicular, face normal).
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
};

/// Anchors every column of @p points on @p surface (closest point by CGAL's AABB tree).
/// Degenerate triangles are never chosen.
/// @throws InputError when the surface has no non-degenerate triangle.
std::vector<SurfaceAnchor> AnchorOnSurface(const Eigen::Matrix3Xd& points,
                                           const geometry::TriangleMesh& surface);

/// The anchored points carried onto @p posed: the same triangles (same faces, new vertex
/// positions), the same barycentric coordinates and the offset in the posed triangle's frame.
/// @pre posed has the faces the anchors were made on. An anchored face that degenerates in
///   @p posed gives non-finite columns; the caller checks.
Eigen::Matrix3Xd PlaceAnchors(const std::vector<SurfaceAnchor>& anchors,
                              const geometry::TriangleMesh& posed);

}  // namespace vb::tools
