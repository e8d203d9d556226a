#pragma once

#include <Eigen/Core>
#include <functional>

#include "geometry/triangle_mesh.h"

namespace vb::perception {

/// Extracts the zero set of @p f (negative inside) on a regular grid of spacing @p h over the
/// box [@p box_min, @p box_max], splitting every cube into six tetrahedra around its main
/// diagonal. Unlike marching cubes, this has no ambiguous cases: when f is positive on the
/// box boundary the result is closed, 2-manifold and oriented outwards (towards f > 0).
/// Grid values within 1e-4 h of zero are nudged positive so no vertex sits on a grid node.
/// @pre h > 0 and the box holds at least one cube.
geometry::TriangleMesh MarchingTetrahedra(const std::function<double(const Eigen::Vector3d&)>& f,
                                          const Eigen::Vector3d& box_min,
                                          const Eigen::Vector3d& box_max, double h);

}  // namespace vb::perception
