#include "morph/similarity_refit.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "io/error.h"
#include "morph/point_index.h"

namespace vb::morph {

Similarity RefitSimilarity(const Eigen::Matrix3Xd& posed, const Eigen::Matrix3Xd& target,
                           const SimilarityRefitOptions& options, WorkerPool* pool) {
  VB_DEMAND(options.keep_fraction > 0.0 && options.keep_fraction <= 1.0);
  Similarity fit;
  if (options.rounds <= 0 || options.samples < 1 || posed.cols() < 4) return fit;
  // Every n-th finite target point, at most `samples` of them.
  const Eigen::Index step = (target.cols() + options.samples - 1) / options.samples;
  std::vector<Eigen::Index> picked;
  picked.reserve(static_cast<std::size_t>(std::min<Eigen::Index>(target.cols(), options.samples)));
  for (Eigen::Index i = 0; i < target.cols(); i += std::max<Eigen::Index>(1, step))
    if (target.col(i).allFinite()) picked.push_back(i);
  const auto count = static_cast<Eigen::Index>(picked.size());
  const auto kept =
      std::min(count, std::max<Eigen::Index>(
                          4, static_cast<Eigen::Index>(std::ceil(options.keep_fraction * count))));
  if (count < 4) return fit;
  const Eigen::Matrix3Xd samples = target(Eigen::all, picked);
  // Nearness to S(posed) is nearness to posed, up to S's scale: the samples are brought back
  // by S's inverse and paired in one kd-tree over the posed points, built once.
  const PointIndex index(posed);
  Eigen::Matrix3Xd back(3, count), from(3, kept), to(3, kept);
  std::vector<double> distance(static_cast<std::size_t>(count));
  std::vector<Eigen::Index> order(static_cast<std::size_t>(count));
  for (int round = 0; round < options.rounds; ++round) {
    const Similarity inverse = fit.Inverse();
    for (Eigen::Index k = 0; k < count; ++k) back.col(k) = inverse(samples.col(k));
    const std::vector<int> nearest = NearestEach(index, back, pool);
    for (Eigen::Index k = 0; k < count; ++k)
      distance[static_cast<std::size_t>(k)] = (posed.col(nearest[k]) - back.col(k)).squaredNorm();
    std::iota(order.begin(), order.end(), Eigen::Index{0});
    // Nearest first, ties by index, so the kept set does not depend on the sort's order.
    std::nth_element(order.begin(), order.begin() + (kept - 1), order.end(),
                     [&](Eigen::Index a, Eigen::Index b) {
                       const double da = distance[static_cast<std::size_t>(a)];
                       const double db = distance[static_cast<std::size_t>(b)];
                       return da < db || (da == db && a < b);
                     });
    for (Eigen::Index m = 0; m < kept; ++m) {
      const Eigen::Index k = order[static_cast<std::size_t>(m)];
      from.col(m) = posed.col(nearest[k]);
      to.col(m) = samples.col(k);
    }
    const Similarity next = Similarity::FromUmeyama(Eigen::umeyama(from, to, true));
    // A fit halving or doubling the template is a collapse onto a degenerate target (all in
    // one spot or on one line), not a correction of a placement.
    if (!next.Usable() || next.scale < 0.5 || next.scale > 2.0) break;
    fit = next;
  }
  return fit;
}

}  // namespace vb::morph
