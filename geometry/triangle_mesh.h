#pragma once

#include <Eigen/Core>

namespace vb::geometry {

/// A triangle mesh. Vertex order is meaningful: two meshes with the same faces correspond
/// vertex by vertex, and every reader, writer and morph keeps that order.
struct TriangleMesh {
  /// 3 by #V vertex positions.
  Eigen::Matrix3Xd V;
  /// 3 by #F vertex indices into V, counter-clockwise seen from outside.
  Eigen::Matrix3Xi F;
  /// 3 by #V unit vertex normals, or 3 by 0 when the mesh carries none.
  Eigen::Matrix3Xd N;

  int num_vertices() const { return static_cast<int>(V.cols()); }
  int num_faces() const { return static_cast<int>(F.cols()); }
  bool has_normals() const { return N.cols() > 0; }
};

/// An unorganised point cloud, with optional per-point normals.
struct PointCloud {
  /// 3 by #P point positions.
  Eigen::Matrix3Xd points;
  /// 3 by #P unit normals, or 3 by 0 when absent.
  Eigen::Matrix3Xd normals;

  int size() const { return static_cast<int>(points.cols()); }
  bool has_normals() const { return normals.cols() > 0; }
};

}  // namespace vb::geometry
