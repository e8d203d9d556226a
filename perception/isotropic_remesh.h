#pragma once

#include "geometry/triangle_mesh.h"

namespace vb::perception {

/// Remeshes a closed, 2-manifold, outward-oriented mesh towards equilateral triangles with
/// edges of about @p target_edge_length (CGAL's isotropic remeshing: splits, collapses,
/// flips and tangential relaxation, projected back onto the input surface). Topology and
/// orientation are kept. This is the only translation unit of vb::perception that includes
/// CGAL, because CGAL headers take about half a minute to compile.
/// @pre target_edge_length > 0.
geometry::TriangleMesh IsotropicRemesh(const geometry::TriangleMesh& mesh,
                                       double target_edge_length, int iterations = 5);

}  // namespace vb::perception
