#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "geometry/mesh_measures.h"
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
  return geometry::BoundingBoxDiagonal(rest) *
         morph::Similarity::FromUmeyama(Eigen::umeyama(rest, truth, true)).scale;
}

/// @p mm as "4 mm" or "0.5 mm" (printf's %g, then @p unit).
inline std::string FormatMm(double mm, const char* unit = " mm") {
  char text[40];
  std::snprintf(text, sizeof text, "%g%s", mm, unit);
  return text;
}

/// @p mm as part of a file's name: "4mm" or "0.5mm".
inline std::string MmLabel(double mm) { return FormatMm(mm, "mm"); }

/// One progress line on stderr per finished step of a long benchmark, so that a run of
/// minutes says how far it is: "[12/96, 41 s, about 287 s left] bench full: cloud sigma 4 mm #2".
/// The time left is the mean time per step so far times the steps left.
class BenchProgress {
 public:
  /// @p label names the benchmark; @p total is its number of steps (at least 1).
  BenchProgress(std::string label, int total)
      : label_(std::move(label)), total_(std::max(1, total)),
        start_(std::chrono::steady_clock::now()) {}

  /// Marks one more step done and prints @p what (the step's own description).
  void Step(const std::string& what) {
    ++done_;
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double left = elapsed / done_ * std::max(0, total_ - done_);
    std::fprintf(stderr, "[%d/%d, %.0f s, about %.0f s left] %s: %s\n", done_, total_, elapsed,
                 left, label_.c_str(), what.c_str());
  }

 private:
  std::string label_;
  int total_;
  int done_ = 0;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace vb::tools
