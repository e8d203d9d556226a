#include "morph/dense_association.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

#include "io/error.h"

namespace vb::morph {

Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, const PointIndex& index, int k,
                                 const Eigen::Matrix3Xd& reference,
                                 const Eigen::Matrix3Xd& reference_normals) {
  VB_DEMAND(k >= 3 && reference.cols() >= 1 && reference.cols() == reference_normals.cols());
  const PointIndex reference_index(reference);
  Eigen::Matrix3Xd normals(3, points.cols());
  std::vector<int> found;
  std::vector<double> distances;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    index.Nearest(points.col(i), k, &found, &distances);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int j : found) mean += points.col(j);
    mean /= static_cast<double>(found.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (int j : found) {
      const Eigen::Vector3d d = points.col(j) - mean;
      scatter += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
    Eigen::Vector3d n = solver.eigenvectors().col(0);  // eigenvalues ascend
    if (n.dot(reference_normals.col(reference_index.Nearest(points.col(i)))) < 0) n = -n;
    normals.col(i) = n;
  }
  return normals;
}

Eigen::Matrix3Xd PlanePoints(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                             const PointIndex& index, int k, bool correct_curvature,
                             double* noise) {
  VB_DEMAND(k >= 1 && normals.cols() == points.cols() && index.size() == points.cols());
  Eigen::Matrix3Xd centroids(3, points.cols());
  // Each point's neighbours, kept for the correction only: k per point, -1 where fewer exist.
  Eigen::MatrixXi neighbours;
  if (correct_curvature) neighbours = Eigen::MatrixXi::Constant(k, points.cols(), -1);
  std::vector<int> found;
  std::vector<double> distances;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    index.Nearest(points.col(i), k, &found, &distances);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int j : found) sum += points.col(j);
    centroids.col(i) = sum / static_cast<double>(found.size());
    if (correct_curvature) std::copy(found.begin(), found.end(), neighbours.col(i).data());
  }
  Eigen::VectorXd offsets(points.cols());
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    offsets[i] = normals.col(i).dot(points.col(i) - centroids.col(i));
  if (noise != nullptr) {
    *noise = 0.0;
    if (points.cols() > 0) {
      const Eigen::VectorXd absolute = offsets.cwiseAbs();
      std::vector<double> magnitudes(absolute.data(), absolute.data() + absolute.size());
      const auto middle = magnitudes.begin() + static_cast<std::ptrdiff_t>(magnitudes.size() / 2);
      std::nth_element(magnitudes.begin(), middle, magnitudes.end());
      *noise = 1.4826 * *middle;
    }
  }
  if (correct_curvature) {
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
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cross, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d R = svd.matrixU() * D * svd.matrixV().transpose();
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
