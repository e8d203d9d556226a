#pragma once

#include <Eigen/Core>

#include "io/triangle_mesh.h"

namespace vb::io {

/// Area-weighted unit vertex normals of @p mesh (3 by #V); a vertex no face uses gets zero.
Eigen::Matrix3Xd VertexNormals(const TriangleMesh& mesh);

/// Enclosed volume by the divergence theorem; positive for a closed, outward-oriented mesh.
double SignedVolume(const TriangleMesh& mesh);

/// Total triangle area.
double SurfaceArea(const TriangleMesh& mesh);

/// Length of the diagonal of the axis-aligned box around the 3 by N points @p P (0 if empty).
double BoundingBoxDiagonal(const Eigen::Ref<const Eigen::Matrix3Xd>& P);

}  // namespace vb::io
