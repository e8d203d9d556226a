#include "morph/cloud_noise.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "io/error.h"
#include "morph/order_statistic.h"

namespace vb::morph {

namespace {

// The quadratic fit's system: at most kMaxNoiseNeighbours rows (dense.noise_neighbours'
// bound), held inline so that neither the decomposition nor its solve allocates.
using FitMatrix = Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::ColMajor, kMaxNoiseNeighbours, 6>;
using FitVector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxNoiseNeighbours, 1>;

// Centroid and principal axes of the points at @p indices; the axes are columns ordered by
// ascending spread, so the first is the normal of their best-fit plane.
struct PrincipalFrame {
  Eigen::Vector3d mean;
  Eigen::Matrix3d axes;
};

PrincipalFrame FitPrincipalFrame(const Eigen::Matrix3Xd& points, const std::vector<int>& indices) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int j : indices) mean += points.col(j);
  mean /= static_cast<double>(indices.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (int j : indices) {
    const Eigen::Vector3d d = points.col(j) - mean;
    scatter += d * d.transpose();
  }
  return {mean, Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors()};
}

}  // namespace

namespace {

// One reading of EstimateNoise at the cloud's own density: the estimate, and the median
// distance from a sample to the farthest neighbour its fit used.
struct NoiseReading {
  double sigma = 0.0;
  double reach = 0.0;
  double density = 0.0;
};

NoiseReading ReadNoise(const Eigen::Matrix3Xd& points, const PointIndex& index, int samples, int k,
                       double radius) {
  const Eigen::Index step = std::max<Eigen::Index>(1, points.cols() / samples);
  std::vector<int> found;
  std::vector<double> distances;
  std::vector<double> residuals;
  std::vector<double> reaches;
  std::vector<double> densities;
  residuals.reserve(static_cast<std::size_t>(points.cols() / step + 1));
  reaches.reserve(residuals.capacity());
  densities.reserve(residuals.capacity());
  FitMatrix A(k, 6);
  FitVector height(k);
  Eigen::ColPivHouseholderQR<FitMatrix> qr(k, 6);
  Eigen::Matrix<double, 6, 1> c;
  // Height above the neighbours' principal plane, as a quadratic in the in-plane coordinates.
  const auto monomials = [](const Eigen::Vector3d& q) {
    return (Eigen::Matrix<double, 1, 6>() << q.y() * q.y(), q.y() * q.z(), q.z() * q.z(), q.y(),
            q.z(), 1.0)
        .finished();
  };
  for (Eigen::Index i = 0; i < points.cols(); i += step) {
    index.Nearest(points.col(i), k + 1, &found, &distances);
    // Leave the point out of its own fit, or the fit takes up part of its noise; and the
    // points beyond the radius, where a quadratic no longer follows a coarse surface.
    std::size_t kept = 0;
    double farthest = 0.0;
    for (std::size_t m = 0; m < found.size() && kept < static_cast<std::size_t>(k); ++m)
      if (found[m] != static_cast<int>(i) && distances[m] <= radius * radius) {
        found[kept++] = found[m];
        farthest = distances[m];
      }
    found.resize(kept);
    const auto n = static_cast<Eigen::Index>(found.size());
    if (n < kMinNoiseNeighbours) continue;
    const PrincipalFrame frame = FitPrincipalFrame(points, found);
    for (Eigen::Index r = 0; r < n; ++r) {
      const Eigen::Vector3d q =
          frame.axes.transpose() * (points.col(found[static_cast<std::size_t>(r)]) - frame.mean);
      A.row(r) = monomials(q);
      height[r] = q.x();
    }
    qr.compute(A.topRows(n));
    c = qr.solve(height.head(n));
    const Eigen::Vector3d q = frame.axes.transpose() * (points.col(i) - frame.mean);
    residuals.push_back(std::abs(q.x() - monomials(q).dot(c)));
    reaches.push_back(std::sqrt(farthest));
    // The n neighbours and the point itself within the farthest's circle on the surface.
    if (farthest > 0.0)
      densities.push_back(static_cast<double>(n + 1) / (std::numbers::pi * farthest));
  }
  if (residuals.empty()) return {};
  return {kMadToSigma * SelectUpperMedian(residuals), SelectUpperMedian(reaches),
          densities.empty() ? 0.0 : SelectUpperMedian(densities)};
}

}  // namespace

NoiseEstimate EstimateNoise(const Eigen::Matrix3Xd& points, const PointIndex& index, int samples,
                            int k, double radius) {
  VB_DEMAND(samples >= 1 && k >= kMinNoiseNeighbours && k <= kMaxNoiseNeighbours && radius > 0 &&
            index.size() == points.cols());
  // Measured on a unit sphere with noise sigma along the normal, the reading against the
  // true sigma by the reach of the 60 nearest: 1.1 at 3-20 sigma, 0.87 at 2.2, 0.77 at 1.9
  // and 0.43 at 1.3 sigma. A reach under this many times the reading may be too short.
  constexpr double kShortReach = 4.0;
  // Thinning by two widens the reach by 1.4; a reading that grows by less than this factor
  // has settled.
  constexpr double kSettled = 1.1;
  constexpr int kMaxStride = 16;
  NoiseEstimate estimate;
  NoiseReading reading = ReadNoise(points, index, samples, k, radius);
  for (int stride = 2; stride <= kMaxStride; stride *= 2) {
    if (reading.sigma == 0.0 || reading.reach >= kShortReach * reading.sigma) break;
    const Eigen::Matrix3Xd thinned = points(Eigen::all, Eigen::seq(0, Eigen::last, stride));
    const PointIndex thinned_index(thinned);
    const NoiseReading wider = ReadNoise(thinned, thinned_index, samples, k, radius);
    if (wider.sigma == 0.0 || wider.reach <= reading.reach) break;  // the radius holds it
    const bool settled = wider.sigma < kSettled * reading.sigma;
    reading = wider;
    estimate.stride = stride;
    if (settled) break;
  }
  estimate.sigma = reading.sigma;
  estimate.density = reading.density;
  return estimate;
}

}  // namespace vb::morph
