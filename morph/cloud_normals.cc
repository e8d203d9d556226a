#include "morph/cloud_normals.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <vector>

#include "io/error.h"

namespace vb::morph {

int NormalPassesForNoise(double relative_noise, int max_passes) {
  return static_cast<int>(std::lround(std::clamp(relative_noise * relative_noise, 1.0,
                                                 static_cast<double>(std::max(1, max_passes)))));
}

Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, const PointIndex& index, int k,
                                 int passes, const Eigen::Matrix3Xd& hints, WorkerPool* pool) {
  VB_DEMAND(k >= 3 && passes >= 1 && index.size() == points.cols() &&
            (hints.cols() == 0 || hints.cols() == points.cols()));
  const Eigen::Index n = points.cols();
  Eigen::Matrix3Xd normals(3, n);
  if (n == 0) return normals;
  // Each point's neighbours (the point itself among them), k or all there are.
  const int neighbours = static_cast<int>(std::min<Eigen::Index>(k, n));
  // Every loop over the points goes to the pool's threads in blocks, each writing only its
  // own columns.
  constexpr Eigen::Index kBlock = 1024;
  Eigen::MatrixXi near(neighbours, n);
  ForEachBlock(pool, n, kBlock, [&](Eigen::Index first, Eigen::Index last) {
    std::vector<int> found;
    std::vector<double> distances;
    for (Eigen::Index i = first; i < last; ++i) {
      index.Nearest(points.col(i), neighbours, &found, &distances);
      std::copy(found.begin(), found.end(), near.col(i).data());
    }
  });
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
    ForEachBlock(pool, n, kBlock, [&](Eigen::Index first, Eigen::Index last) {
      for (Eigen::Index i = first; i < last; ++i) {
        widened.col(i).setZero();
        for (int m = 0; m < neighbours; ++m) widened.col(i) += moments.col(near(m, i));
        widened.col(i) /= static_cast<double>(neighbours);
      }
    });
    moments.swap(widened);
  }
  const bool oriented = hints.cols() > 0;
  ForEachBlock(pool, n, kBlock, [&](Eigen::Index first, Eigen::Index last) {
    for (Eigen::Index i = first; i < last; ++i) {
      const auto m = moments.col(i);
      const Eigen::Vector3d mean = m.segment<3>(1) / m[0];
      Eigen::Matrix3d covariance;
      covariance << m[4], m[5], m[6], m[5], m[7], m[8], m[6], m[8], m[9];
      covariance = covariance / m[0] - mean * mean.transpose();
      Eigen::Vector3d normal =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvectors().col(0);
      if (oriented && normal.dot(hints.col(i)) < 0) normal = -normal;
      normals.col(i) = normal;
    }
  });
  return normals;
}

void RefitNormals(const Eigen::Matrix3Xd& points, const PointIndex& index,
                  const std::vector<int>& counts, const std::vector<double>& radii,
                  Eigen::Matrix3Xd* normals, WorkerPool* pool) {
  VB_DEMAND(static_cast<Eigen::Index>(counts.size()) == points.cols() &&
            radii.size() == counts.size() && normals->cols() == points.cols() &&
            index.size() == points.cols());
  constexpr Eigen::Index kBlock = 1024;
  ForEachBlock(pool, points.cols(), kBlock, [&](Eigen::Index first, Eigen::Index last) {
    std::vector<int> found;
    std::vector<double> distances;  // squared
    PointIndex::RadiusList radius_list;
    for (Eigen::Index j = first; j < last; ++j) {
      const auto at = static_cast<std::size_t>(j);
      if (counts[at] <= 0) continue;
      index.Within(points.col(j), radii[at], counts[at], &found, &distances, &radius_list);
      const std::size_t within = found.size();
      if (within < 3) continue;
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (std::size_t m = 0; m < within; ++m) mean += points.col(found[m]);
      mean /= static_cast<double>(within);
      Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
      for (std::size_t m = 0; m < within; ++m) {
        const Eigen::Vector3d d = points.col(found[m]) - mean;
        scatter += d * d.transpose();
      }
      Eigen::Vector3d normal =
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
      if (normal.dot(normals->col(j)) < 0) normal = -normal;
      normals->col(j) = normal;
    }
  });
}

}  // namespace vb::morph
