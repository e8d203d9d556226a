#include "morph/cut_turn.h"

#include <Eigen/SVD>
#include <cmath>
#include <vector>

#include "morph/feature_association.h"

namespace vb::morph {

namespace {

// A rotation is fixed by normals only when they spread in two directions: the second
// singular value of their correlation must be at least this fraction of the first.
constexpr double kMinNormalSpread = 0.1;

}  // namespace

std::optional<Eigen::Matrix3d> SurfaceTurn(const io::CutAnnotation& cut, const LineExtent& extent,
                                           const geometry::TriangleMesh& rest,
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
  return NearestRotation(svd);
}

double BandScale(const io::CutAnnotation& cut, const LineExtent& extent,
                 const geometry::TriangleMesh& rest, const geometry::TriangleMesh& morphed,
                 double band) {
  std::vector<int> in_band;
  for (int v = 0; v < rest.num_vertices(); ++v)
    if (NearTheCut(cut, extent, rest.V.col(v), band)) in_band.push_back(v);
  if (in_band.size() < 2) return 0.0;
  Eigen::Vector3d rest_mean = Eigen::Vector3d::Zero(), morphed_mean = Eigen::Vector3d::Zero();
  for (int v : in_band) {
    rest_mean += rest.V.col(v);
    morphed_mean += morphed.V.col(v);
  }
  rest_mean /= static_cast<double>(in_band.size());
  morphed_mean /= static_cast<double>(in_band.size());
  double rest_spread = 0.0, morphed_spread = 0.0;
  for (int v : in_band) {
    rest_spread += (rest.V.col(v) - rest_mean).squaredNorm();
    morphed_spread += (morphed.V.col(v) - morphed_mean).squaredNorm();
  }
  return rest_spread > 0 ? std::sqrt(morphed_spread / rest_spread) : 0.0;
}

}  // namespace vb::morph
