#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "io/mesh_measures.h"
#include "morph/feature_association.h"

namespace vb::tools {

/// Median of @p v (NaN when empty).
inline double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// The @p q quantile (0..1) of @p v, nearest rank (NaN when empty).
inline double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, rank == 0 ? 0 : rank - 1)];
}

/// The size relative errors are taken against, as the paper means it: the template's
/// bounding-box diagonal in its own frame (@p rest, its vertices) times the scale of the best
/// similarity taking @p rest onto @p truth (same vertex order). Unlike the diagonal of
/// @p truth's own axis-aligned box, it does not grow when the target is turned.
inline double TrueSize(const Eigen::Matrix3Xd& rest, const Eigen::Matrix3Xd& truth) {
  return io::BoundingBoxDiagonal(rest) *
         morph::Similarity::FromUmeyama(Eigen::umeyama(rest, truth, true)).scale;
}

}  // namespace vb::tools
