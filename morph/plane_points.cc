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

Eigen::Matrix3Xd PlanePoints(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                             const PointIndex& index, int k, double radius, bool correct_curvature,
                             WorkerPool* pool) {
  VB_DEMAND(k >= 1 && radius > 0 && normals.cols() == points.cols() &&
            index.size() == points.cols());
  const Eigen::Index n = points.cols();
  // The points go to the pool's threads in blocks; each block writes only its own columns.
  constexpr Eigen::Index kBlock = 1024;
  Eigen::Matrix3Xd centroids(3, n);
  // Each point's neighbours, kept for the correction only: k per point, -1 where fewer exist.
  Eigen::MatrixXi neighbours;
  if (correct_curvature) neighbours = Eigen::MatrixXi::Constant(k, n, -1);
  ForEachBlock(pool, n, kBlock, [&](Eigen::Index first, Eigen::Index last) {
    std::vector<int> found;
    std::vector<double> distances;
    for (Eigen::Index i = first; i < last; ++i) {
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
  });
  if (correct_curvature) {
    Eigen::VectorXd offsets(n);
    for (Eigen::Index i = 0; i < n; ++i)
      offsets[i] = normals.col(i).dot(points.col(i) - centroids.col(i));
    ForEachBlock(pool, n, kBlock, [&](Eigen::Index first, Eigen::Index last) {
      for (Eigen::Index i = first; i < last; ++i) {
        double sum = 0.0;
        int count = 0;
        for (Eigen::Index m = 0; m < k && neighbours(m, i) >= 0; ++m, ++count)
          sum += offsets[neighbours(m, i)];
        centroids.col(i) += normals.col(i) * (sum / static_cast<double>(count));
      }
    });
  }
  return centroids;
}

}  // namespace vb::morph
