#include "morph/point_index.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <nanoflann.hpp>
#include <utility>

#include "io/error.h"
#include "morph/worker_pool.h"

namespace vb::morph {

struct PointIndex::Tree {
  using Adaptor =
      nanoflann::KDTreeEigenMatrixAdaptor<Eigen::Matrix3Xd, 3, nanoflann::metric_L2_Simple, false>;
  explicit Tree(const Eigen::Matrix3Xd& points) : adaptor(3, std::cref(points), 16) {
    adaptor.index->buildIndex();
  }
  Adaptor adaptor;
};

PointIndex::PointIndex(const Eigen::Matrix3Xd& points)
    : points_(points), tree_(std::make_unique<Tree>(points)) {}

PointIndex::~PointIndex() = default;

int PointIndex::Nearest(const Eigen::Vector3d& q) const {
  VB_DEMAND(points_.cols() > 0);
  Eigen::Index index = 0;
  double squared = 0.0;
  tree_->adaptor.query(q.data(), 1, &index, &squared);
  return static_cast<int>(index);
}

void PointIndex::Nearest(const Eigen::Vector3d& q, int k, std::vector<int>* indices,
                         std::vector<double>* squared_distances) const {
  const auto n = static_cast<std::size_t>(std::clamp<Eigen::Index>(k, 0, points_.cols()));
  if (n == 0) {  // nanoflann's result set reads its last slot, which an empty one lacks
    indices->clear();
    squared_distances->clear();
    return;
  }
  // The tree's indices land on the stack for the usual few neighbours, so a query makes no
  // allocation once the caller's vectors have grown.
  constexpr std::size_t kOnStack = 64;
  std::array<Eigen::Index, kOnStack> on_stack;
  std::vector<Eigen::Index> on_heap;
  Eigen::Index* found = on_stack.data();
  if (n > kOnStack) {
    on_heap.resize(n);
    found = on_heap.data();
  }
  squared_distances->resize(n);
  nanoflann::KNNResultSet<double, Eigen::Index> result(n);
  result.init(found, squared_distances->data());
  tree_->adaptor.index->findNeighbors(result, q.data(), nanoflann::SearchParams());
  const std::size_t count = result.size();
  indices->resize(count);
  squared_distances->resize(count);
  for (std::size_t i = 0; i < count; ++i) (*indices)[i] = static_cast<int>(found[i]);
}

void PointIndex::Within(const Eigen::Vector3d& q, double radius, int max_count,
                        std::vector<int>* indices, std::vector<double>* squared_distances,
                        RadiusList* scratch) const {
  VB_DEMAND(radius >= 0.0 && max_count >= 0);
  indices->clear();
  squared_distances->clear();
  if (max_count == 0) return;
  RadiusList own;  // nanoflann clears a list it is given and keeps its capacity
  RadiusList& found = scratch != nullptr ? *scratch : own;
  // nanoflann keeps squared distances strictly below its bound (for this metric the bound is
  // a squared distance); d^2 < nextafter(r^2) is d^2 <= r^2.
  tree_->adaptor.index->radiusSearch(q.data(), std::nextafter(radius * radius, HUGE_VAL), found,
                                     nanoflann::SearchParams(32, 0.0F, false));
  const auto nearer = [](const auto& a, const auto& b) {
    return a.second < b.second || (a.second == b.second && a.first < b.first);
  };
  const auto kept = std::min(found.size(), static_cast<std::size_t>(max_count));
  std::partial_sort(found.begin(), found.begin() + static_cast<std::ptrdiff_t>(kept), found.end(),
                    nearer);
  indices->resize(kept);
  squared_distances->resize(kept);
  for (std::size_t i = 0; i < kept; ++i) {
    (*indices)[i] = static_cast<int>(found[i].first);
    (*squared_distances)[i] = found[i].second;
  }
}

std::vector<int> NearestEach(const PointIndex& index, const Eigen::Matrix3Xd& queries,
                             WorkerPool* pool) {
  std::vector<int> nearest(static_cast<std::size_t>(queries.cols()));
  constexpr std::int64_t kBlock = 2048;
  ForEachBlock(pool, queries.cols(), kBlock, [&](std::int64_t first, std::int64_t last) {
    for (std::int64_t i = first; i < last; ++i)
      nearest[static_cast<std::size_t>(i)] = index.Nearest(queries.col(i));
  });
  return nearest;
}

}  // namespace vb::morph
