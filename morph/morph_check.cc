#include "morph/morph_check.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "io/error.h"
#include "morph/order_statistic.h"
#include "morph/point_index.h"

namespace vb::morph {

MorphCheck CheckMorph(const TemplateModel& model, const CoarseResult& coarse,
                      const DenseResult& dense, const MorphCheckOptions& options,
                      std::span<const int> nearest_vertex) {
  const Eigen::Matrix3Xd& target = dense.target;
  MorphCheck check;
  check.noise = dense.noise;
  if (std::isfinite(coarse.runner_up_disagreement) && coarse.runner_up_disagreement > 0)
    check.ambiguity = coarse.choice_disagreement / coarse.runner_up_disagreement;

  // The model's normalised frame has the template's size as unit; the coarse similarity
  // takes it to the target's units.
  const double size = coarse.association.from_to.scale;
  if (target.cols() > 0 && dense.mesh.V.cols() > 0) {
    VB_DEMAND(nearest_vertex.empty() ||
              static_cast<Eigen::Index>(nearest_vertex.size()) == target.cols());
    std::vector<int> found;
    if (nearest_vertex.empty()) {
      found = NearestEach(PointIndex(dense.mesh.V), target);
      nearest_vertex = found;
    }
    const double limit =
        (options.explained_distance + options.noise_allowance * dense.noise) * size;
    long far = 0;
    std::vector<double> distances(static_cast<std::size_t>(target.cols()));
    for (Eigen::Index i = 0; i < target.cols(); ++i) {
      const int v = nearest_vertex[static_cast<std::size_t>(i)];
      const double d = (dense.mesh.V.col(v) - target.col(i)).norm();
      distances[static_cast<std::size_t>(i)] = d;
      if (d > limit) ++far;
    }
    check.unexplained = static_cast<double>(far) / static_cast<double>(target.cols());
    if (size > 0) check.reach = SelectQuantile(distances, 0.99) / size;
  }

  std::vector<double> logs;
  logs.reserve(3 * static_cast<std::size_t>(model.mesh.F.cols()));
  double edge_sum = 0.0;  // template sizes
  long edges = 0;
  for (Eigen::Index f = 0; f < model.mesh.F.cols(); ++f) {
    for (int e = 0; e < 3; ++e) {
      const int a = model.mesh.F(e, f), b = model.mesh.F((e + 1) % 3, f);
      if (a > b) continue;  // each interior edge once (its other face has it the other way)
      const double length = (model.V.col(a) - model.V.col(b)).norm();
      edge_sum += length;
      ++edges;
      const double rest = size * length;
      const double now = (dense.mesh.V.col(a) - dense.mesh.V.col(b)).norm();
      if (rest > 0 && now > 0) logs.push_back(std::abs(std::log(now / rest)));
    }
  }
  check.reach_allowance =
      options.reach_noise * check.noise +
      (edges > 0 ? edge_sum / static_cast<double>(edges) / std::sqrt(3.0) : 0.0);
  if (!logs.empty()) check.stretch = SelectQuantile(logs, 0.9);

  // Unknown (and refused below) unless both meshes hold the template's vertices.
  check.size = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Index n = model.mesh.V.cols();
  if (n > 0 && dense.mesh.V.cols() == n) {
    const Eigen::Vector3d rest_centre = model.mesh.V.rowwise().mean();
    const Eigen::Vector3d now_centre = dense.mesh.V.rowwise().mean();
    const double rest = (model.mesh.V.colwise() - rest_centre).squaredNorm();
    const double now = (dense.mesh.V.colwise() - now_centre).squaredNorm();
    if (rest > 0) check.size = std::sqrt(now / rest);
  }
  const double from_size =
      check.size >= options.min_size && check.size <= options.max_size ? 1.0 : 0.0;

  const double from_ambiguity =
      std::clamp((1.0 - check.ambiguity) / (1.0 - options.ambiguity_start), 0.0, 1.0);
  const double u = check.unexplained / options.unexplained_scale;
  const double from_unexplained = 1.0 / (1.0 + u * u);
  const double from_stretch = std::clamp(
      (options.stretch_end - check.stretch) / (options.stretch_end - options.stretch_start), 0.0,
      1.0);
  // No reach (no target, or no size) is no sign that the morph covers the target.
  const bool reach_read = std::isfinite(check.reach) && std::isfinite(check.reach_allowance);
  const double from_reach =
      reach_read ? std::clamp((options.reach_end - (check.reach - check.reach_allowance)) /
                                  (options.reach_end - options.reach_start),
                              0.0, 1.0)
                 : 0.0;
  check.confidence = from_size * from_ambiguity * from_unexplained * from_stretch * from_reach;
  char why[300];
  const double worst =
      std::min({from_size, from_ambiguity, from_unexplained, from_stretch, from_reach});
  if (worst < 0.9) {
    if (worst == from_size)
      std::snprintf(why, sizeof(why),
                    "the morph is %.3g times the template's size, outside [%.3g, %.3g]: a "
                    "target in other units, or another kind of body",
                    check.size, options.min_size, options.max_size);
    else if (worst == from_ambiguity)
      std::snprintf(why, sizeof(why),
                    "placement ambiguous: a placement turned elsewhere fits %.0f %% as well",
                    100.0 * check.ambiguity);
    else if (worst == from_reach && !reach_read)
      std::snprintf(why, sizeof(why), "no target points to check the morph against");
    else if (worst == from_reach)
      std::snprintf(why, sizeof(why),
                    "the farthest 1 %% of the target lies %.1f %% of the template's size from the "
                    "morph, %.1f %% of the size beyond what the noise and the vertex spacing "
                    "explain: a part put elsewhere, or something attached to the carcass (a "
                    "gambrel in the region of interest?)",
                    100.0 * check.reach, 100.0 * (check.reach - check.reach_allowance));
    else if (worst == from_unexplained)
      std::snprintf(why, sizeof(why), "%.0f %% of the target is not covered by the morph",
                    100.0 * check.unexplained);
    else
      std::snprintf(why, sizeof(why), "the morph stretched the template by %.0f %%",
                    100.0 * (std::exp(check.stretch) - 1.0));
    check.concern = why;
  }
  return check;
}

std::string DescribeCheck(const MorphCheck& check) {
  char line[200];
  std::snprintf(line, sizeof(line),
                "%.2f (ambiguity %.3f, unexplained %.3f, reach %.3f (noise and spacing %.3f), "
                "stretch %.3f, size %.3f)",
                check.confidence, check.ambiguity, check.unexplained, check.reach,
                check.reach_allowance, check.stretch, check.size);
  return check.concern.empty() ? std::string(line) : std::string(line) + ": " + check.concern;
}

}  // namespace vb::morph
