#include "morph/cut_transfer.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <cmath>
#include <optional>

#include "io/error.h"
#include "io/mesh_measures.h"
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

// Where a cut line lies on the template: its centroid and the largest distance from it.
struct LineExtent {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

LineExtent ExtentOf(const io::CutAnnotation& cut, const io::TriangleMesh& rest) {
  LineExtent e;
  for (const io::SurfacePoint& p : cut.line) e.centre += io::Evaluate(rest, p);
  e.centre /= static_cast<double>(cut.line.size());
  for (const io::SurfacePoint& p : cut.line)
    e.radius = std::max(e.radius, (io::Evaluate(rest, p) - e.centre).norm());
  return e;
}

// Template vertices within @p band of the cut's plane and close to its line, so that other
// limbs crossing the plane do not count.
bool NearTheCut(const io::CutAnnotation& cut, const LineExtent& extent,
                const Eigen::Vector3d& vertex, double band) {
  return (vertex - extent.centre).norm() <= extent.radius + band &&
         std::abs(cut.plane.SignedDistance(vertex)) <= band;
}

// Which way the part before the cut lies on the morphed mesh: from the template vertices in
// a band on the far side of the cut to those in the band on its near side.
Eigen::Vector3d TowardsPartBefore(const io::CutAnnotation& cut, const LineExtent& extent,
                                  const io::TriangleMesh& rest, const io::TriangleMesh& morphed,
                                  double band) {
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

// A rotation is fixed by normals only when they spread in two directions: the second
// singular value of their correlation must be at least this fraction of the first.
constexpr double kMinNormalSpread = 0.1;

// Wahba's problem on normals: the rotation that best takes the template's vertex normals in
// a band either side of @p cut onto the morphed template's normals at the same vertices,
// each weighted down as it leans towards the cut's normal and left out past max_lean (the
// cosine between them). Empty when fewer than min_vertices count, or their normals do not
// fix a rotation.
std::optional<Eigen::Matrix3d> SurfaceTurn(const io::CutAnnotation& cut, const LineExtent& extent,
                                           const io::TriangleMesh& rest,
                                           const Eigen::Matrix3Xd& rest_normals,
                                           const Eigen::Matrix3Xd& morphed_normals, double band,
                                           double max_lean, int min_vertices) {
  Eigen::Matrix3d correlation = Eigen::Matrix3d::Zero();
  int used = 0;
  for (int v = 0; v < rest.num_vertices(); ++v) {
    if (!NearTheCut(cut, extent, rest.V.col(v), band)) continue;
    // Normals leaning towards the cut's own normal belong to where the surface tapers; a
    // stretch along the body turns those, not the ones the saw meets square on.
    const double lean = rest_normals.col(v).dot(cut.plane.normal) / max_lean;
    if (std::abs(lean) >= 1.0) continue;
    correlation += (1.0 - lean * lean) * morphed_normals.col(v) * rest_normals.col(v).transpose();
    ++used;
  }
  if (used < min_vertices) return std::nullopt;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(correlation,
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  if (svd.singularValues()(1) < kMinNormalSpread * svd.singularValues()(0)) return std::nullopt;
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
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
  const Eigen::Matrix3Xd rest_normals = rest.has_normals() ? rest.N : io::VertexNormals(rest);
  const Eigen::Matrix3Xd morphed_normals =
      morphed.has_normals() ? morphed.N : io::VertexNormals(morphed);
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
      const LineExtent extent = ExtentOf(cut, rest);
      t.plane = FitPlane(t.line);
      double sum = 0.0;
      for (const Eigen::Vector3d& p : t.line) sum += std::pow(t.plane.SignedDistance(p), 2);
      t.fit_rms = std::sqrt(sum / static_cast<double>(t.line.size()));
      if (options.normal_band > 0) {
        if (const std::optional<Eigen::Matrix3d> turn =
                SurfaceTurn(cut, extent, rest, rest_normals, morphed_normals,
                            options.normal_band * template_size, options.normal_max_lean,
                            options.min_band_vertices)) {
          t.plane.normal = (*turn * cut.plane.normal).normalized();
          t.oriented_by_normals = true;
        }
      }
      const Eigen::Vector3d towards =
          TowardsPartBefore(cut, extent, rest, morphed, options.side_band * template_size);
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
