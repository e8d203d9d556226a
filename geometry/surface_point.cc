#include "geometry/surface_point.h"

#include "io/error.h"

namespace vb::geometry {

Eigen::Vector3d Evaluate(const TriangleMesh& mesh, const SurfacePoint& p) {
  VB_DEMAND(p.face >= 0 && p.face < mesh.num_faces());
  return p.barycentric[0] * mesh.V.col(mesh.F(0, p.face)) +
         p.barycentric[1] * mesh.V.col(mesh.F(1, p.face)) +
         p.barycentric[2] * mesh.V.col(mesh.F(2, p.face));
}

}  // namespace vb::geometry
