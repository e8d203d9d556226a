#include "morph/cut_transfer.h"

#include <Eigen/Eigenvalues>
#include <cmath>

#include "io/error.h"
#include "io/surface_point.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

// Least-squares plane of @p points: centroid and direction of least spread.
io::Plane FitPlane(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  return io::Plane{.point = mean, .normal = solver.eigenvectors().col(0).normalized()};
}

// Which way the part before the cut lies on the morphed mesh: from the template vertices in
// a band on the far side of the cut to those in the band on its near side, both taken close
// to the cut line so other limbs crossing the plane do not count.
Eigen::Vector3d TowardsPartBefore(const io::CutAnnotation& cut, const io::TriangleMesh& rest,
                                  const io::TriangleMesh& morphed, double band) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const io::SurfacePoint& p : cut.line) centre += io::Evaluate(rest, p);
  centre /= static_cast<double>(cut.line.size());
  double radius = 0.0;
  for (const io::SurfacePoint& p : cut.line)
    radius = std::max(radius, (io::Evaluate(rest, p) - centre).norm());
  Eigen::Vector3d before = Eigen::Vector3d::Zero(), after = Eigen::Vector3d::Zero();
  int n_before = 0, n_after = 0;
  for (int v = 0; v < rest.num_vertices(); ++v) {
    if ((rest.V.col(v) - centre).norm() > radius + band) continue;
    const double d = cut.plane.SignedDistance(rest.V.col(v));
    if (d > 0 && d < band) {
      before += morphed.V.col(v);
      ++n_before;
    } else if (d <= 0 && d > -band) {
      after += morphed.V.col(v);
      ++n_after;
    }
  }
  if (n_before == 0 || n_after == 0) return Eigen::Vector3d::Zero();
  return before / n_before - after / n_after;
}

}  // namespace

std::vector<TransferredCut> TransferCuts(const io::Annotations& annotations,
                                         const io::TriangleMesh& rest,
                                         const io::TriangleMesh& morphed,
                                         const Eigen::Matrix3Xd& target,
                                         const Eigen::Matrix3Xd& target_normals, double size,
                                         const CutTransferOptions& options) {
  VB_DEMAND(rest.num_vertices() == morphed.num_vertices() && target.cols() > 0 &&
            target_normals.cols() == target.cols() && size > 0);
  const double template_size = (rest.V.rowwise().maxCoeff() - rest.V.rowwise().minCoeff()).norm();
  const PointIndex index(target);
  const double radius = options.support_radius * size;
  std::vector<int> found;
  std::vector<double> distances;
  std::vector<TransferredCut> out;
  for (const io::CutAnnotation& cut : annotations.cuts) {
    TransferredCut t;
    t.name = cut.name;
    int seen = 0;
    for (const io::SurfacePoint& sp : cut.line) {
      const Eigen::Vector3d p = io::Evaluate(morphed, sp);
      index.Nearest(p, options.surface_neighbours, &found, &distances);
      Eigen::Vector3d mean = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
      int n = 0;
      for (std::size_t k = 0; k < found.size(); ++k) {
        if (distances[k] > radius * radius) continue;
        mean += target.col(found[k]);
        normal += target_normals.col(found[k]);
        ++n;
      }
      if (n == 0 || normal.norm() < 1e-12) {
        t.line.push_back(p);  // unseen: the morphed template stands in for the target
        continue;
      }
      mean /= n;
      normal.normalize();
      const double offset = normal.dot(p - mean);
      t.line.push_back(p - offset * normal);
      t.gap += std::abs(offset);
      ++seen;
    }
    t.coverage = cut.line.empty() ? 0.0 : static_cast<double>(seen) / cut.line.size();
    t.gap = seen ? t.gap / seen : 0.0;
    if (t.line.size() >= 3) {
      t.plane = FitPlane(t.line);
      double sum = 0.0;
      for (const Eigen::Vector3d& p : t.line) sum += std::pow(t.plane.SignedDistance(p), 2);
      t.fit_rms = std::sqrt(sum / static_cast<double>(t.line.size()));
      const Eigen::Vector3d towards =
          TowardsPartBefore(cut, rest, morphed, options.side_band * template_size);
      if (towards.dot(t.plane.normal) < 0) t.plane.normal = -t.plane.normal;
      const double fit = t.fit_rms / (options.fit_scale * size);
      const double gap = t.gap / (options.gap_scale * size);
      t.confidence = t.coverage / (1.0 + fit * fit) / (1.0 + gap * gap);
    }
    out.push_back(std::move(t));
  }
  return out;
}

std::vector<io::PartMeasure> CutParts(const io::TriangleMesh& mesh,
                                      const std::vector<TransferredCut>& cuts) {
  std::vector<io::Plane> planes;
  for (const TransferredCut& c : cuts) planes.push_back(c.plane);
  return io::MeasureParts(mesh, planes);
}

}  // namespace vb::morph
