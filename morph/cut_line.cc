#include "morph/cut_line.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "geometry/surface_point.h"

namespace vb::morph {

geometry::Plane FitPlane(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  return geometry::Plane{.point = mean, .normal = solver.eigenvectors().col(0).normalized()};
}

LineExtent ExtentOf(const io::CutAnnotation& cut, const geometry::TriangleMesh& rest) {
  LineExtent e;
  for (const geometry::SurfacePoint& p : cut.line) e.centre += geometry::Evaluate(rest, p);
  e.centre /= static_cast<double>(cut.line.size());
  for (const geometry::SurfacePoint& p : cut.line)
    e.radius = std::max(e.radius, (geometry::Evaluate(rest, p) - e.centre).norm());
  return e;
}

bool NearTheCut(const io::CutAnnotation& cut, const LineExtent& extent,
                const Eigen::Vector3d& vertex, double band) {
  return (vertex - extent.centre).norm() <= extent.radius + band &&
         std::abs(cut.plane.SignedDistance(vertex)) <= band;
}

Eigen::Vector3d TowardsPartBefore(const io::CutAnnotation& cut, const LineExtent& extent,
                                  const geometry::TriangleMesh& rest,
                                  const geometry::TriangleMesh& morphed, double band) {
  Eigen::Vector3d before = Eigen::Vector3d::Zero(), after = Eigen::Vector3d::Zero();
  int n_before = 0, n_after = 0;
  for (int v = 0; v < rest.num_vertices(); ++v) {
    if (!NearTheCut(cut, extent, rest.V.col(v), band)) continue;
    if (cut.plane.SignedDistance(rest.V.col(v)) > 0) {
      before += morphed.V.col(v);
      ++n_before;
    } else {
      after += morphed.V.col(v);
      ++n_after;
    }
  }
  if (n_before == 0 || n_after == 0) return Eigen::Vector3d::Zero();
  return before / n_before - after / n_after;
}

LineOnTarget CarryLine(const io::CutAnnotation& cut, const geometry::TriangleMesh& morphed,
                       const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& target_normals,
                       const PointIndex& index, int neighbours, double radius) {
  LineOnTarget out;
  std::vector<int> found;
  std::vector<double> distances;
  int seen = 0;
  for (const geometry::SurfacePoint& sp : cut.line) {
    const Eigen::Vector3d p = geometry::Evaluate(morphed, sp);
    index.Nearest(p, neighbours, &found, &distances);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
    int n = 0;
    for (std::size_t k = 0; k < found.size(); ++k) {
      if (distances[k] > radius * radius) continue;
      mean += target.col(found[k]);
      normal += target_normals.col(found[k]);
      ++n;
    }
    if (n == 0 || normal.norm() < 1e-12) {
      out.points.push_back(p);
      continue;
    }
    mean /= n;
    normal.normalize();
    const double offset = normal.dot(p - mean);
    out.points.push_back(p - offset * normal);
    out.gap += std::abs(offset);
    ++seen;
  }
  out.coverage = cut.line.empty() ? 0.0 : static_cast<double>(seen) / cut.line.size();
  out.gap = seen ? out.gap / seen : 0.0;
  return out;
}

}  // namespace vb::morph
