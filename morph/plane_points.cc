#include "morph/plane_points.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "io/error.h"

namespace vb::morph {

int NeighboursForNoise(int fewest, int most, double relative_noise) {
  return static_cast<int>(
      std::lround(std::clamp(fewest * relative_noise * relative_noise, static_cast<double>(fewest),
                             static_cast<double>(std::max(fewest, most)))));
}

double CurvatureOffset(double curvature_sum, double sigma) {
  return std::clamp(sigma * sigma * curvature_sum, -sigma, sigma);
}

namespace {

// Over the listed points: each one's centroid of its k nearest within the radius (column m
// for which[m]) and, when @p neighbours is given, those neighbours (column m, -1 where fewer
// exist). Each block writes only its own columns.
void Centroids(const Eigen::Matrix3Xd& points, const PointIndex& index, int k, double radius,
               std::span<const int> which, WorkerPool* pool, Eigen::Matrix3Xd* centroids,
               Eigen::MatrixXi* neighbours) {
  constexpr Eigen::Index kBlock = 1024;
  const auto n = static_cast<Eigen::Index>(which.size());
  *centroids = Eigen::Matrix3Xd(3, n);
  if (neighbours != nullptr) *neighbours = Eigen::MatrixXi::Constant(k, n, -1);
  ForEachBlock(pool, n, kBlock, [&](Eigen::Index first, Eigen::Index last) {
    std::vector<int> found;
    std::vector<double> distances;
    for (Eigen::Index m = first; m < last; ++m) {
      index.Nearest(points.col(which[static_cast<std::size_t>(m)]), k, &found, &distances);
      // The nearest (the point itself) always counts; the rest only within the radius.
      std::size_t kept = std::min<std::size_t>(1, found.size());
      while (kept < found.size() && distances[kept] <= radius * radius) ++kept;
      found.resize(kept);
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int j : found) sum += points.col(j);
      centroids->col(m) = sum / static_cast<double>(found.size());
      if (neighbours != nullptr) std::copy(found.begin(), found.end(), neighbours->col(m).data());
    }
  });
}

}  // namespace

Eigen::Matrix3Xd PlanePointsOf(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                               const PointIndex& index, int k, double radius,
                               bool correct_curvature, std::span<const int> which,
                               WorkerPool* pool) {
  VB_DEMAND(k >= 1 && radius > 0 && normals.cols() == points.cols() &&
            index.size() == points.cols());
  for (int i : which) VB_DEMAND(i >= 0 && i < points.cols());
  Eigen::Matrix3Xd centroids;
  Eigen::MatrixXi neighbours;
  Centroids(points, index, k, radius, which, pool, &centroids,
            correct_curvature ? &neighbours : nullptr);
  if (!correct_curvature) return centroids;
  // The correction reads every neighbour's offset from its own centroid: the listed points'
  // centroids are at hand, the other neighbours' are made here (slot: where a point's centroid
  // is, -1 for none yet; the listed first, then the others).
  std::vector<int> slot(static_cast<std::size_t>(points.cols()), -1);
  for (std::size_t m = 0; m < which.size(); ++m)
    slot[static_cast<std::size_t>(which[m])] = static_cast<int>(m);
  std::vector<int> others;
  for (Eigen::Index m = 0; m < neighbours.cols(); ++m) {
    for (Eigen::Index r = 0; r < k && neighbours(r, m) >= 0; ++r) {
      const auto j = static_cast<std::size_t>(neighbours(r, m));
      if (slot[j] >= 0) continue;
      slot[j] = static_cast<int>(which.size() + others.size());
      others.push_back(neighbours(r, m));
    }
  }
  Eigen::Matrix3Xd other_centroids;
  Centroids(points, index, k, radius, others, pool, &other_centroids, nullptr);
  const auto n = static_cast<Eigen::Index>(which.size());
  const auto centroid = [&](int j) -> Eigen::Vector3d {
    const int s = slot[static_cast<std::size_t>(j)];
    return s < n ? centroids.col(s) : other_centroids.col(s - n);
  };
  const auto offset = [&](int j) { return normals.col(j).dot(points.col(j) - centroid(j)); };
  Eigen::Matrix3Xd corrected(3, n);
  constexpr Eigen::Index kBlock = 1024;
  ForEachBlock(pool, n, kBlock, [&](Eigen::Index first, Eigen::Index last) {
    for (Eigen::Index m = first; m < last; ++m) {
      double sum = 0.0;
      int count = 0;
      for (Eigen::Index r = 0; r < k && neighbours(r, m) >= 0; ++r, ++count)
        sum += offset(neighbours(r, m));
      corrected.col(m) = centroids.col(m) + normals.col(which[static_cast<std::size_t>(m)]) *
                                                (sum / static_cast<double>(count));
    }
  });
  return corrected;
}

Eigen::Matrix3Xd PlanePoints(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                             const PointIndex& index, int k, double radius, bool correct_curvature,
                             WorkerPool* pool) {
  std::vector<int> all(static_cast<std::size_t>(points.cols()));
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return PlanePointsOf(points, normals, index, k, radius, correct_curvature, all, pool);
}

}  // namespace vb::morph
