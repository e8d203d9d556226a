#pragma once

#include <Eigen/Core>

#include "geometry/triangle_mesh.h"

namespace vb::geometry {

/// Area-weighted unit vertex normals of @p mesh (3 by #V); a vertex no face uses gets zero.
Eigen::Matrix3Xd VertexNormals(const TriangleMesh& mesh);

/// Sum of the two principal curvatures at each vertex (twice the mean curvature; positive
/// where the surface bends away from its normals, 2 / r on a sphere of radius r with outward
/// normals), from @p N (3 by #V unit vertex normals): twice the mean over the vertex's edges
/// of the normal curvature along each, (n_b - n_a).(x_b - x_a) / |x_b - x_a|^2. An edge
/// shared by two faces counts twice; a vertex without edges gets 0.
Eigen::VectorXd CurvatureSums(const TriangleMesh& mesh, const Eigen::Matrix3Xd& N);

/// Enclosed volume by the divergence theorem; positive for a closed, outward-oriented mesh.
double SignedVolume(const TriangleMesh& mesh);

/// Total triangle area.
double SurfaceArea(const TriangleMesh& mesh);

/// Each vertex's share of the surface: a third of the area of every face it is a corner of
/// (#V entries, in the mesh's units squared; 0 for a vertex no face uses).
/// @pre every index in mesh.F is in [0, #V).
Eigen::VectorXd VertexAreas(const TriangleMesh& mesh);

/// Length of the diagonal of the axis-aligned box around the 3 by N points @p P (0 if empty).
double BoundingBoxDiagonal(const Eigen::Ref<const Eigen::Matrix3Xd>& P);

}  // namespace vb::geometry
