#include "morph/association_filter.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <span>
#include <utility>

#include "io/error.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"

namespace vb::morph {

namespace {

// The rigidity residual of eq. (12) at one point over its remaining neighbours, with the
// rotation fitted to the same weighted edges (Kabsch). An edge of no length on the first side
// (two pairs sharing a point there) says nothing of rigidity and is left out; a point with no
// other edge scores 0.
double RigidityResidual(const Eigen::Matrix3Xd& a1, const Eigen::Matrix3Xd& a2, int i,
                        std::span<const int> neighbours) {
  constexpr double kNoLength = 1e-24;  // squared
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  int edges = 0;
  for (int j : neighbours) {
    const Eigen::Vector3d e1 = a1.col(i) - a1.col(j);
    if (!(e1.squaredNorm() > kNoLength)) continue;
    const Eigen::Vector3d e2 = a2.col(i) - a2.col(j);
    cross += (e2 * e1.transpose()) / e1.squaredNorm();
    ++edges;
  }
  if (edges == 0) return 0.0;
  const Eigen::Matrix3d R = NearestRotation(
      Eigen::JacobiSVD<Eigen::Matrix3d>(cross, Eigen::ComputeFullU | Eigen::ComputeFullV));
  double r = 0.0;
  for (int j : neighbours) {
    const Eigen::Vector3d e1 = a1.col(i) - a1.col(j);
    if (!(e1.squaredNorm() > kNoLength)) continue;
    const Eigen::Vector3d e2 = a2.col(i) - a2.col(j);
    r += (e2 - R * e1).squaredNorm() / e1.squaredNorm();
  }
  // Per edge: a point whose neighbours were trimmed keeps a comparable score.
  return r / static_cast<double>(edges);
}

// Lists of ints, one per point, each in its own fixed slice of one array; removing an entry
// keeps the others' order.
class FlatLists {
 public:
  // @p sizes: each list's capacity; every list starts empty.
  explicit FlatLists(const std::vector<int>& sizes)
      : first_(sizes.size() + 1, 0), count_(sizes.size(), 0) {
    for (std::size_t i = 0; i < sizes.size(); ++i) first_[i + 1] = first_[i] + sizes[i];
    values_.resize(static_cast<std::size_t>(first_.back()));
  }
  std::span<const int> operator[](int i) const {
    const auto at = static_cast<std::size_t>(i);
    return {values_.data() + first_[at], static_cast<std::size_t>(count_[at])};
  }
  void Append(int i, int value) {
    const auto at = static_cast<std::size_t>(i);
    values_[static_cast<std::size_t>(first_[at] + count_[at]++)] = value;
  }
  void Remove(int i, int value) {
    const auto at = static_cast<std::size_t>(i);
    int* begin = values_.data() + first_[at];
    count_[at] = static_cast<int>(std::remove(begin, begin + count_[at], value) - begin);
  }
  void Clear(int i) { count_[static_cast<std::size_t>(i)] = 0; }

 private:
  std::vector<int> first_;  // list i occupies values_[first_[i], first_[i + 1])
  std::vector<int> count_;
  std::vector<int> values_;
};

}  // namespace

std::vector<bool> FilterAssociations(const Eigen::Matrix3Xd& a1, const Eigen::Matrix3Xd& a2,
                                     const AssociationFilterOptions& options) {
  VB_DEMAND(a1.cols() == a2.cols() && options.neighbours >= 2);
  const int m = static_cast<int>(a1.cols());
  std::vector<bool> kept(static_cast<std::size_t>(m), true);
  if (m <= options.neighbours) return kept;

  // (a) the k-nearest graph on the template side; (b) the same edges on the target side.
  // users: the i such that j is one of i's neighbours, in increasing order.
  FlatLists neighbours(std::vector<int>(static_cast<std::size_t>(m), options.neighbours + 1));
  std::vector<int> user_sizes(static_cast<std::size_t>(m), 0);
  {
    const PointIndex index(a1);
    std::vector<int> found;
    std::vector<double> distances;
    for (int i = 0; i < m; ++i) {
      index.Nearest(a1.col(i), options.neighbours + 1, &found, &distances);
      for (int j : found) {
        if (j == i) continue;
        neighbours.Append(i, j);
        ++user_sizes[static_cast<std::size_t>(j)];
      }
    }
  }
  FlatLists users(user_sizes);
  for (int i = 0; i < m; ++i)
    for (int j : neighbours[i]) users.Append(j, i);

  // (c) residuals, with running sums for the mean and deviation, and a max-heap of
  // (residual, point). A rescored point's old entry stays in the heap and is skipped when it
  // comes up: an entry counts while its point is kept and its residual is the point's own.
  std::vector<double> r(static_cast<std::size_t>(m));
  std::vector<std::pair<double, int>> heap;
  heap.reserve(2 * static_cast<std::size_t>(m));
  double sum = 0.0, sum_squares = 0.0;
  for (int i = 0; i < m; ++i) {
    r[static_cast<std::size_t>(i)] = RigidityResidual(a1, a2, i, neighbours[i]);
    heap.emplace_back(r[static_cast<std::size_t>(i)], i);
    sum += r[static_cast<std::size_t>(i)];
    sum_squares += r[static_cast<std::size_t>(i)] * r[static_cast<std::size_t>(i)];
  }
  std::make_heap(heap.begin(), heap.end());
  int remaining = m;
  const auto current = [&](const std::pair<double, int>& entry) {
    const auto at = static_cast<std::size_t>(entry.second);
    return kept[at] && entry.first == r[at];
  };
  auto forget = [&](int i) {
    const double ri = r[static_cast<std::size_t>(i)];
    sum -= ri;
    sum_squares -= ri * ri;
  };

  // (d) trim the worst until the termination criterion holds.
  const int max_trimmed = static_cast<int>(options.max_trimmed_fraction * m);
  for (int trimmed = 0; trimmed < max_trimmed && remaining > 2; ++trimmed) {
    while (!heap.empty() && !current(heap.front())) {
      std::pop_heap(heap.begin(), heap.end());
      heap.pop_back();
    }
    if (heap.empty()) break;  // only NaN residuals left: none is ranked
    const double n = static_cast<double>(remaining);
    const double mean = sum / n;
    const double deviation = std::sqrt(std::max(0.0, sum_squares / n - mean * mean));
    const auto [worst_r, worst] = heap.front();
    if (worst_r <= mean + 2.0 * deviation || worst_r < options.min_residual) break;
    forget(worst);
    --remaining;
    kept[static_cast<std::size_t>(worst)] = false;
    for (int j : neighbours[worst]) users.Remove(j, worst);
    // Only the points that used the trimmed one as a neighbour change.
    for (int u : users[worst]) {
      if (!kept[static_cast<std::size_t>(u)]) continue;
      neighbours.Remove(u, worst);
      forget(u);
      const double ru = RigidityResidual(a1, a2, u, neighbours[u]);
      r[static_cast<std::size_t>(u)] = ru;
      heap.emplace_back(ru, u);
      std::push_heap(heap.begin(), heap.end());
      sum += ru;
      sum_squares += ru * ru;
    }
    users.Clear(worst);
  }
  return kept;
}

}  // namespace vb::morph
