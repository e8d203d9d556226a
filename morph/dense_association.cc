#include "morph/dense_association.h"

#include <cmath>
#include <limits>

#include "io/error.h"

namespace vb::morph {

DenseAssociation AssociateDense(const Eigen::Matrix3Xd& source,
                                const Eigen::Matrix3Xd& source_normals,
                                const std::vector<int>& samples, const Eigen::Matrix3Xd& target,
                                const Eigen::Matrix3Xd& target_normals,
                                const PointIndex& target_index,
                                const DenseAssociationOptions& options) {
  VB_DEMAND(options.candidates >= 1 && target_index.size() == target.cols());
  DenseAssociation out;
  out.source.reserve(samples.size());
  out.target.reserve(samples.size());
  std::vector<int> found;
  std::vector<double> distances;
  for (int i : samples) {
    const Eigen::Vector3d v = source.col(i);
    const Eigen::Vector3d o = source_normals.col(i);
    target_index.Nearest(v, options.candidates, &found, &distances);
    double best = std::numeric_limits<double>::infinity();
    int chosen = -1;
    for (std::size_t c = 0; c < found.size(); ++c) {
      const double distance = std::sqrt(distances[c]);
      const double cosine = o.dot(target_normals.col(found[c]));
      if (distance > options.max_distance || cosine < options.min_normal_cosine) continue;
      const double cost = options.lambda * distance - cosine;
      if (cost < best) {
        best = cost;
        chosen = found[c];
      }
    }
    if (chosen < 0) continue;
    out.source.push_back(i);
    out.target.push_back(chosen);
  }
  return out;
}

}  // namespace vb::morph
