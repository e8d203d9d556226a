#include "morph/surface_distance.h"

#include <limits>

#include "morph/point_index.h"

namespace vb::morph {

// Region tests on the barycentric parameters (Ericson, Real-Time Collision Detection 5.1.5).
Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

SurfaceDistance::SurfaceDistance(const geometry::TriangleMesh& mesh)
    : mesh_(mesh), faces_of_vertex_(static_cast<std::size_t>(mesh.num_vertices())) {
  for (int f = 0; f < mesh.num_faces(); ++f)
    for (int k = 0; k < 3; ++k) faces_of_vertex_[static_cast<std::size_t>(mesh.F(k, f))].push_back(f);
  index_ = std::make_unique<morph::PointIndex>(mesh_.V);
}

SurfaceDistance::~SurfaceDistance() = default;

double SurfaceDistance::operator()(const Eigen::Vector3d& p) const {
  std::vector<int> nearest;
  std::vector<double> squared;
  index_->Nearest(p, 8, &nearest, &squared);
  double best = std::numeric_limits<double>::infinity();
  for (int v : nearest) {
    for (int f : faces_of_vertex_[static_cast<std::size_t>(v)]) {
      const Eigen::Vector3d q = ClosestPointOnTriangle(p, mesh_.V.col(mesh_.F(0, f)),
                                                       mesh_.V.col(mesh_.F(1, f)),
                                                       mesh_.V.col(mesh_.F(2, f)));
      best = std::min(best, (q - p).norm());
    }
  }
  return best;
}

}  // namespace vb::morph
