#pragma once

#include <Eigen/Core>
#include <functional>

#include "geometry/triangle_mesh.h"

namespace vb::geometry {

/// @p count points drawn uniformly over the area of @p surface (a degenerate face has none),
/// each with its face's unit normal (oriented as the face winds).
/// @param uniform  draws a number in [0, 1); three per point, in the order face, u, v.
/// @param[out] points, normals  3 by @p count.
/// @pre count >= 0; every index in surface.F is in [0, #V).
/// @throws std::invalid_argument when the surface has no area (no face, or all degenerate).
void SampleSurface(const TriangleMesh& surface, int count, const std::function<double()>& uniform,
                   Eigen::Matrix3Xd* points, Eigen::Matrix3Xd* normals);

}  // namespace vb::geometry
