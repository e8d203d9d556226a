#include "morph/part_volumes.h"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <span>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "io/error.h"
#include "morph/point_index.h"

namespace vb::morph {

std::vector<geometry::PartMeasure> CutParts(const geometry::TriangleMesh& mesh,
                                            const std::vector<TransferredCut>& cuts) {
  std::vector<geometry::Plane> planes;
  for (const TransferredCut& c : cuts) planes.push_back(c.plane);
  return geometry::MeasureParts(mesh, planes);
}

namespace {

// Signed distance from @p p to @p mesh near its vertex @p v (outward positive): to the
// nearest of the faces round v that p projects into, else along v's normal. Exact where the
// closest point lies in v's one ring, which the nearest vertex's does on a mesh finer than
// its curvature.
double SignedDistanceNear(const geometry::TriangleMesh& mesh, const Eigen::Matrix3Xd& normals,
                          std::span<const int> faces_of_v, int v, const Eigen::Vector3d& p) {
  double distance = normals.col(v).dot(p - mesh.V.col(v));
  double nearest = std::numeric_limits<double>::infinity();
  for (int f : faces_of_v) {
    const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
    const Eigen::Vector3d b = mesh.V.col(mesh.F(1, f));
    const Eigen::Vector3d c = mesh.V.col(mesh.F(2, f));
    Eigen::Vector3d n = (b - a).cross(c - a);
    const double twice_area = n.norm();
    if (!(twice_area > 0)) continue;
    n /= twice_area;
    const double height = n.dot(p - a);
    const Eigen::Vector3d q = p - height * n;
    if (n.dot((b - q).cross(c - q)) < 0 || n.dot((c - q).cross(a - q)) < 0 ||
        n.dot((a - q).cross(b - q)) < 0)
      continue;  // projects outside this face
    if (std::abs(height) < nearest) {
      nearest = std::abs(height);
      distance = height;
    }
  }
  return distance;
}

}  // namespace

std::vector<geometry::PartMeasure> CutTargetParts(const geometry::TriangleMesh& morphed,
                                                  const std::vector<TransferredCut>& cuts,
                                                  const Eigen::Matrix3Xd& target, double size,
                                                  const PartVolumeOptions& options,
                                                  std::span<const int> nearest_vertex) {
  VB_DEMAND(size > 0 && options.max_offset > 0);
  VB_DEMAND(nearest_vertex.empty() ||
            static_cast<Eigen::Index>(nearest_vertex.size()) == target.cols());
  std::vector<geometry::PartMeasure> parts = CutParts(morphed, cuts);
  if (parts.empty() || morphed.num_vertices() == 0) return parts;
  Eigen::Matrix3Xd computed_normals;  // for a mesh without
  const Eigen::Matrix3Xd& normals =
      morphed.has_normals() ? morphed.N : (computed_normals = geometry::VertexNormals(morphed));
  const geometry::VertexFaces faces_of(morphed);
  std::vector<int> found;
  if (nearest_vertex.empty()) {
    found = NearestEach(PointIndex(morphed.V), target);
    nearest_vertex = found;
  }
  const double max_offset = options.max_offset * size;
  std::vector<double> sum(parts.size(), 0.0);
  std::vector<int> count(parts.size(), 0);
  for (Eigen::Index j = 0; j < target.cols(); ++j) {
    const Eigen::Vector3d p = target.col(j);
    const int v = nearest_vertex[static_cast<std::size_t>(j)];
    const double d = SignedDistanceNear(morphed, normals, faces_of[v], v, p);
    if (!(std::abs(d) <= max_offset)) continue;
    // Part k lies on the negative side of cuts 0..k-1 and the positive side of cut k.
    std::size_t part = 0;
    while (part < cuts.size() && cuts[part].plane.SignedDistance(p) < 0) ++part;
    sum[part] += d;
    ++count[part];
  }
  for (std::size_t k = 0; k < parts.size(); ++k)
    if (count[k] >= options.min_points) parts[k].volume += parts[k].area * sum[k] / count[k];
  return parts;
}

}  // namespace vb::morph
