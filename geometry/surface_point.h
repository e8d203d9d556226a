#pragma once

#include <Eigen/Core>

#include "geometry/triangle_mesh.h"

namespace vb::geometry {

/// A point on a triangle mesh surface, as a face and barycentric coordinates in that face's
/// vertex order. It follows any deformation of the mesh that keeps the faces.
struct SurfacePoint {
  int face = 0;
  Eigen::Vector3d barycentric = Eigen::Vector3d(1.0 / 3, 1.0 / 3, 1.0 / 3);
};

/// The position of @p p on @p mesh. @pre p.face is a face of mesh.
Eigen::Vector3d Evaluate(const TriangleMesh& mesh, const SurfacePoint& p);

}  // namespace vb::geometry
