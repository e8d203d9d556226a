#include "morph/association_filter.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <set>

#include "io/error.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"

namespace vb::morph {

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
