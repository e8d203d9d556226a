#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "geometry/triangle_mesh.h"

namespace vb::morph {

class PointIndex;

/// Distance from points to a triangle mesh's surface: the least exact point-to-triangle
/// distance over the faces around the 8 mesh vertices nearest to the query. Approximate: it
/// can miss the closest face when triangles are large against the query's distance.
/// Holds a reference to the mesh, which must outlive it and not change.
class SurfaceDistance {
 public:
  explicit SurfaceDistance(const geometry::TriangleMesh& mesh);
  explicit SurfaceDistance(geometry::TriangleMesh&&) = delete;
  ~SurfaceDistance();

  double operator()(const Eigen::Vector3d& p) const;

 private:
  const geometry::TriangleMesh& mesh_;
  std::vector<std::vector<int>> faces_of_vertex_;
  std::unique_ptr<morph::PointIndex> index_;
};

/// The point of triangle (a, b, c) closest to @p p.
Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c);

}  // namespace vb::morph
