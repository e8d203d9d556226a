#pragma once

#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

namespace vb::morph {

/// A kd-tree (nanoflann) over the columns of a 3 by N matrix, for nearest-neighbour queries.
/// Holds a reference to the points: they must outlive the index and not change.
class PointIndex {
 public:
  explicit PointIndex(const Eigen::Matrix3Xd& points);
  ~PointIndex();
  PointIndex(const PointIndex&) = delete;
  PointIndex& operator=(const PointIndex&) = delete;

  /// Index of the point nearest to @p q. @pre the index holds at least one point.
  int Nearest(const Eigen::Vector3d& q) const;
  /// The (up to) @p k nearest points to @p q, nearest first, with squared distances; none for
  /// k <= 0.
  void Nearest(const Eigen::Vector3d& q, int k, std::vector<int>* indices,
               std::vector<double>* squared_distances) const;

  /// Where Within lists every point within the radius before it keeps the nearest.
  using RadiusList = std::vector<std::pair<Eigen::Index, double>>;

  /// The points at most @p radius from @p q, the nearest @p max_count of them when there are
  /// more: nearest first, equal distances by index, with squared distances. The same as
  /// Nearest(q, max_count) cut at the radius, but for the order of equal distances, found
  /// without ranking the farther points. Safe to call from several threads at once, each
  /// with its own @p scratch: given one, a query allocates nothing once the scratch has held
  /// the longest list; without, each call makes its own and frees it.
  /// @pre radius >= 0 (not NaN), max_count >= 0.
  void Within(const Eigen::Vector3d& q, double radius, int max_count, std::vector<int>* indices,
              std::vector<double>* squared_distances, RadiusList* scratch = nullptr) const;

  int size() const { return static_cast<int>(points_.cols()); }

 private:
  struct Tree;
  const Eigen::Matrix3Xd& points_;
  std::unique_ptr<Tree> tree_;
};

class WorkerPool;

/// For each column of @p queries, the index of the nearest of @p index's points: the queries
/// shared among @p pool's threads (when given), each writing only its own entry, so the result
/// is the same on any number of threads. @pre the index holds at least one point.
std::vector<int> NearestEach(const PointIndex& index, const Eigen::Matrix3Xd& queries,
                             WorkerPool* pool = nullptr);

}  // namespace vb::morph
