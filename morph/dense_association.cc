#include "morph/dense_association.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "io/error.h"
#include "morph/feature_association.h"

namespace vb::morph {

namespace {

// Fewest neighbours a noise sample is fitted to: twice the quadratic's six coefficients.
constexpr Eigen::Index kMinNoiseNeighbours = 12;

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

Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, const PointIndex& index, int k,
                                 int passes, const Eigen::Matrix3Xd& reference,
                                 const Eigen::Matrix3Xd& reference_normals) {
  VB_DEMAND(k >= 3 && passes >= 1 && index.size() == points.cols() && reference.cols() >= 1 &&
            reference.cols() == reference_normals.cols());
  const Eigen::Index n = points.cols();
  Eigen::Matrix3Xd normals(3, n);
  if (n == 0) return normals;
  // Each point's neighbours (the point itself among them), k or all there are.
  const int neighbours = static_cast<int>(std::min<Eigen::Index>(k, n));
  Eigen::MatrixXi near(neighbours, n);
  std::vector<int> found;
  std::vector<double> distances;
  for (Eigen::Index i = 0; i < n; ++i) {
    index.Nearest(points.col(i), neighbours, &found, &distances);
    std::copy(found.begin(), found.end(), near.col(i).data());
  }
  // Moments about the cloud's centroid, so the covariance keeps its digits: per point the
  // count (row 0), the sum (rows 1-3) and the outer products xx, xy, xz, yy, yz, zz (4-9).
  using Moments = Eigen::Matrix<double, 10, Eigen::Dynamic>;
  const Eigen::Vector3d centre = points.rowwise().mean();
  Moments moments(10, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d x = points.col(i) - centre;
    moments.col(i) << 1.0, x, x.x() * x.x(), x.x() * x.y(), x.x() * x.z(), x.y() * x.y(),
        x.y() * x.z(), x.z() * x.z();
  }
  Moments widened(10, n);
  for (int pass = 0; pass < passes; ++pass) {
    for (Eigen::Index i = 0; i < n; ++i) {
      widened.col(i).setZero();
      for (int m = 0; m < neighbours; ++m) widened.col(i) += moments.col(near(m, i));
      widened.col(i) /= static_cast<double>(neighbours);
    }
    moments.swap(widened);
  }
  const PointIndex reference_index(reference);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto m = moments.col(i);
    const Eigen::Vector3d mean = m.segment<3>(1) / m[0];
    Eigen::Matrix3d covariance;
    covariance << m[4], m[5], m[6], m[5], m[7], m[8], m[6], m[8], m[9];
    covariance = covariance / m[0] - mean * mean.transpose();
    Eigen::Vector3d normal =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvectors().col(0);
    if (normal.dot(reference_normals.col(reference_index.Nearest(points.col(i)))) < 0)
      normal = -normal;
    normals.col(i) = normal;
  }
  return normals;
}

namespace {

// One reading of EstimateNoise at the cloud's own density: the estimate, and the median
// distance from a sample to the farthest neighbour its fit used.
struct NoiseReading {
  double sigma = 0.0;
  double reach = 0.0;
};

NoiseReading ReadNoise(const Eigen::Matrix3Xd& points, const PointIndex& index, int samples, int k,
                       double radius) {
  const Eigen::Index step = std::max<Eigen::Index>(1, points.cols() / samples);
  std::vector<int> found;
  std::vector<double> distances;
  std::vector<double> residuals;
  std::vector<double> reaches;
  residuals.reserve(static_cast<std::size_t>(points.cols() / step + 1));
  reaches.reserve(residuals.capacity());
  Eigen::MatrixXd A(k, 6);
  Eigen::VectorXd height(k);
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
    const Eigen::VectorXd c = A.topRows(n).colPivHouseholderQr().solve(height.head(n));
    const Eigen::Vector3d q = frame.axes.transpose() * (points.col(i) - frame.mean);
    residuals.push_back(std::abs(q.x() - monomials(q).dot(c)));
    reaches.push_back(std::sqrt(farthest));
  }
  if (residuals.empty()) return {};
  const auto median = [](std::vector<double>& values) {
    const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
    std::nth_element(values.begin(), middle, values.end());
    return *middle;
  };
  return {1.4826 * median(residuals), median(reaches)};
}

}  // namespace

NoiseEstimate EstimateNoise(const Eigen::Matrix3Xd& points, const PointIndex& index, int samples,
                            int k, double radius) {
  VB_DEMAND(samples >= 1 && k >= 10 && radius > 0 && index.size() == points.cols());
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
  return estimate;
}

int NeighboursForNoise(int fewest, int most, double relative_noise) {
  return static_cast<int>(
      std::lround(std::clamp(fewest * relative_noise * relative_noise, static_cast<double>(fewest),
                             static_cast<double>(std::max(fewest, most)))));
}

double CurvatureOffset(double curvature_sum, double sigma) {
  return std::clamp(sigma * sigma * curvature_sum, -sigma, sigma);
}

Eigen::Matrix3Xd PlanePoints(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                             const PointIndex& index, int k, double radius,
                             bool correct_curvature) {
  VB_DEMAND(k >= 1 && radius > 0 && normals.cols() == points.cols() &&
            index.size() == points.cols());
  Eigen::Matrix3Xd centroids(3, points.cols());
  // Each point's neighbours, kept for the correction only: k per point, -1 where fewer exist.
  Eigen::MatrixXi neighbours;
  if (correct_curvature) neighbours = Eigen::MatrixXi::Constant(k, points.cols(), -1);
  std::vector<int> found;
  std::vector<double> distances;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    index.Nearest(points.col(i), k, &found, &distances);
    // The nearest (the point itself) always counts; the rest only within the radius.
    std::size_t kept = std::min<std::size_t>(1, found.size());
    while (kept < found.size() && distances[kept] <= radius * radius) ++kept;
    found.resize(kept);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int j : found) sum += points.col(j);
    centroids.col(i) = sum / static_cast<double>(found.size());
    if (correct_curvature) std::copy(found.begin(), found.end(), neighbours.col(i).data());
  }
  if (correct_curvature) {
    Eigen::VectorXd offsets(points.cols());
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      offsets[i] = normals.col(i).dot(points.col(i) - centroids.col(i));
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      double sum = 0.0;
      int count = 0;
      for (Eigen::Index n = 0; n < k && neighbours(n, i) >= 0; ++n, ++count)
        sum += offsets[neighbours(n, i)];
      centroids.col(i) += normals.col(i) * (sum / static_cast<double>(count));
    }
  }
  return centroids;
}

DenseAssociation AssociateDense(const Eigen::Matrix3Xd& source,
                                const Eigen::Matrix3Xd& source_normals,
                                const std::vector<int>& samples, const Eigen::Matrix3Xd& target,
                                const Eigen::Matrix3Xd& target_normals,
                                const PointIndex& target_index,
                                const DenseAssociationOptions& options) {
  VB_DEMAND(options.candidates >= 1 && target_index.size() == target.cols());
  DenseAssociation out;
  out.source.reserve(samples.size());
  out.target.reserve(samples.size());
  std::vector<int> found;
  std::vector<double> distances;
  for (int i : samples) {
    const Eigen::Vector3d v = source.col(i);
    const Eigen::Vector3d o = source_normals.col(i);
    target_index.Nearest(v, options.candidates, &found, &distances);
    double best = std::numeric_limits<double>::infinity();
    int chosen = -1;
    for (std::size_t c = 0; c < found.size(); ++c) {
      const double distance = std::sqrt(distances[c]);
      const double cosine = o.dot(target_normals.col(found[c]));
      if (distance > options.max_distance || cosine < options.min_normal_cosine) continue;
      const double cost = options.lambda * distance - cosine;
      if (cost < best) {
        best = cost;
        chosen = found[c];
      }
    }
    if (chosen < 0) continue;
    out.source.push_back(i);
    out.target.push_back(chosen);
  }
  return out;
}

namespace {

// The rigidity residual of eq. (12) at one point over its remaining neighbours, with the
// rotation fitted to the same weighted edges (Kabsch).
double RigidityResidual(const Eigen::Matrix3Xd& a1, const Eigen::Matrix3Xd& a2, int i,
                        const std::vector<int>& neighbours) {
  if (neighbours.empty()) return 0.0;
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  for (int j : neighbours) {
    const Eigen::Vector3d e1 = a1.col(i) - a1.col(j);
    const Eigen::Vector3d e2 = a2.col(i) - a2.col(j);
    cross += (e2 * e1.transpose()) / std::max(e1.squaredNorm(), 1e-24);
  }
  const Eigen::Matrix3d R = NearestRotation(
      Eigen::JacobiSVD<Eigen::Matrix3d>(cross, Eigen::ComputeFullU | Eigen::ComputeFullV));
  double r = 0.0;
  for (int j : neighbours) {
    const Eigen::Vector3d e1 = a1.col(i) - a1.col(j);
    const Eigen::Vector3d e2 = a2.col(i) - a2.col(j);
    r += (e2 - R * e1).squaredNorm() / std::max(e1.squaredNorm(), 1e-24);
  }
  // Per edge: a point whose neighbours were trimmed keeps a comparable score.
  return r / static_cast<double>(neighbours.size());
}

}  // namespace

std::vector<bool> FilterAssociations(const Eigen::Matrix3Xd& a1, const Eigen::Matrix3Xd& a2,
                                     const AssociationFilterOptions& options) {
  VB_DEMAND(a1.cols() == a2.cols() && options.neighbours >= 2);
  const int m = static_cast<int>(a1.cols());
  std::vector<bool> kept(static_cast<std::size_t>(m), true);
  if (m <= options.neighbours) return kept;

  // (a) the k-nearest graph on the template side; (b) the same edges on the target side.
  std::vector<std::vector<int>> neighbours(static_cast<std::size_t>(m));
  std::vector<std::vector<int>> users(static_cast<std::size_t>(m));  // i such that j in N(i)
  {
    const PointIndex index(a1);
    std::vector<int> found;
    std::vector<double> distances;
    for (int i = 0; i < m; ++i) {
      index.Nearest(a1.col(i), options.neighbours + 1, &found, &distances);
      for (int j : found) {
        if (j == i) continue;
        neighbours[static_cast<std::size_t>(i)].push_back(j);
        users[static_cast<std::size_t>(j)].push_back(i);
      }
    }
  }

  // (c) residuals, ordered, with running sums for the mean and deviation.
  std::vector<double> r(static_cast<std::size_t>(m));
  std::set<std::pair<double, int>> order;
  double sum = 0.0, sum_squares = 0.0;
  for (int i = 0; i < m; ++i) {
    r[static_cast<std::size_t>(i)] =
        RigidityResidual(a1, a2, i, neighbours[static_cast<std::size_t>(i)]);
    order.emplace(r[static_cast<std::size_t>(i)], i);
    sum += r[static_cast<std::size_t>(i)];
    sum_squares += r[static_cast<std::size_t>(i)] * r[static_cast<std::size_t>(i)];
  }
  auto forget = [&](int i) {
    const double ri = r[static_cast<std::size_t>(i)];
    order.erase({ri, i});
    sum -= ri;
    sum_squares -= ri * ri;
  };

  // (d) trim the worst until the termination criterion holds.
  const int max_trimmed = static_cast<int>(options.max_trimmed_fraction * m);
  for (int trimmed = 0; trimmed < max_trimmed && order.size() > 2; ++trimmed) {
    const double n = static_cast<double>(order.size());
    const double mean = sum / n;
    const double deviation = std::sqrt(std::max(0.0, sum_squares / n - mean * mean));
    const auto [worst_r, worst] = *order.rbegin();
    if (worst_r <= mean + 2.0 * deviation || worst_r < options.min_residual) break;
    forget(worst);
    kept[static_cast<std::size_t>(worst)] = false;
    for (int j : neighbours[static_cast<std::size_t>(worst)])
      std::erase(users[static_cast<std::size_t>(j)], worst);
    // Only the points that used the trimmed one as a neighbour change.
    for (int u : users[static_cast<std::size_t>(worst)]) {
      if (!kept[static_cast<std::size_t>(u)]) continue;
      std::erase(neighbours[static_cast<std::size_t>(u)], worst);
      forget(u);
      const double ru = RigidityResidual(a1, a2, u, neighbours[static_cast<std::size_t>(u)]);
      r[static_cast<std::size_t>(u)] = ru;
      order.emplace(ru, u);
      sum += ru;
      sum_squares += ru * ru;
    }
    users[static_cast<std::size_t>(worst)].clear();
  }
  return kept;
}

}  // namespace vb::morph
