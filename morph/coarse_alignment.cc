#include "morph/coarse_alignment.h"

#include <chrono>
#include <limits>
#include <numbers>

#include "io/error.h"
#include "io/mesh_measures.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The data term of one template feature node, in the template's normalised frame.
PointConstraint FeatureConstraint(const Eigen::Vector3d& rest, const Eigen::Vector3d& target,
                                  const NodeWeights& w, int column) {
  PointConstraint c;
  c.rest = rest;
  c.target = target;
  for (Eigen::Index k = 0; k < w.nodes.rows(); ++k) {
    if (w.nodes(k, column) < 0) continue;
    c.nodes.push_back(w.nodes(k, column));
    c.weights.push_back(w.weights(k, column));
  }
  return c;
}

// How badly the template, placed by `fit`, and the target disagree as surfaces: the mean of
// closest-point distances both ways between a few hundred samples of each.
double SurfaceDisagreement(const Eigen::Matrix3Xd& template_samples,
                           const Eigen::Matrix3Xd& target_samples, const PointIndex& target_index,
                           const Eigen::Matrix3Xd& target, const Similarity& fit) {
  Eigen::Matrix3Xd placed(3, template_samples.cols());
  for (Eigen::Index i = 0; i < placed.cols(); ++i) placed.col(i) = fit(template_samples.col(i));
  double sum = 0.0;
  for (Eigen::Index i = 0; i < placed.cols(); ++i)
    sum += (target.col(target_index.Nearest(placed.col(i))) - placed.col(i)).norm();
  const PointIndex placed_index(placed);
  for (Eigen::Index i = 0; i < target_samples.cols(); ++i) {
    sum += (placed.col(placed_index.Nearest(target_samples.col(i))) - target_samples.col(i)).norm();
  }
  return sum / static_cast<double>(placed.cols() + target_samples.cols());
}

Eigen::Matrix3Xd EveryNth(const Eigen::Matrix3Xd& points, int wanted) {
  const Eigen::Index step = std::max<Eigen::Index>(1, points.cols() / wanted);
  Eigen::Matrix3Xd out(3, (points.cols() + step - 1) / step);
  for (Eigen::Index i = 0, k = 0; i < points.cols(); i += step, ++k) out.col(k) = points.col(i);
  return out;
}

}  // namespace

CoarseResult AlignCoarse(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                         const CoarseOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  CoarseResult result;
  if (target.cols() < 50) {
    result.error = "target has " + std::to_string(target.cols()) + " points, fewer than 50";
    return result;
  }
  if (!target.allFinite()) {
    result.error = "target has non-finite coordinates";
    return result;
  }

  // Target skeleton and features, computed in the target's own normalised frame.
  auto phase = std::chrono::steady_clock::now();
  const double target_size = io::BoundingBoxDiagonal(target);
  SkeletonGraph skeleton;
  try {
    skeleton = CloudSkeleton(target, options.skeleton);
  } catch (const InputError& e) {
    result.error = std::string("target ") + e.what();
    return result;
  }
  FeatureOptions features = options.features;
  features.min_branch_length *= target_size;
  features.junction_merge_distance *= target_size;
  result.target_features = ExtractFeatureNodes(skeleton, features);
  result.skeleton_seconds = Since(phase);

  // Association: template (normalised) -> target (its own units).
  phase = std::chrono::steady_clock::now();
  // Eq. (3) ranks skeleton pairings; the best few are then checked against the surfaces, as
  // pairings with similar skeleton residuals can place the carcass upside down.
  const std::vector<Association> candidates =
      AssociateFeatureNodes(model.features, result.target_features, options.association);
  if (!candidates.empty()) {
    const Eigen::Matrix3Xd template_samples = EveryNth(model.V, options.verification_samples);
    const Eigen::Matrix3Xd target_samples = EveryNth(target, options.verification_samples);
    const PointIndex target_index(target);
    double cos_tilt = -1.0;
    Eigen::Vector3d template_up = Eigen::Vector3d::UnitZ(), target_up = Eigen::Vector3d::UnitZ();
    if (options.upright) {
      template_up = options.upright->template_up.normalized();
      target_up = options.upright->target_up.normalized();
      cos_tilt = std::cos(options.upright->max_tilt_deg * std::numbers::pi / 180.0);
    }
    std::vector<double> disagreements;
    double best = std::numeric_limits<double>::infinity();
    for (const Association& candidate : candidates) {
      if ((candidate.from_to.R * template_up).dot(target_up) < cos_tilt) {
        disagreements.push_back(std::numeric_limits<double>::infinity());
        continue;
      }
      disagreements.push_back(SurfaceDisagreement(template_samples, target_samples, target_index,
                                                  target, candidate.from_to));
      if (disagreements.back() < best) {
        best = disagreements.back();
        result.association = candidate;
      }
    }
    const double scale = result.association.from_to.scale;  // target units per template size
    result.disagreement = best / scale;
    result.runner_up_disagreement = std::numeric_limits<double>::infinity();
    const double cos_distinct = std::cos(options.distinct_angle_deg * std::numbers::pi / 180.0);
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const Eigen::Matrix3d relative =
          candidates[k].from_to.R * result.association.from_to.R.transpose();
      const double cos_angle = 0.5 * (relative.trace() - 1.0);
      if (cos_angle < cos_distinct)
        result.runner_up_disagreement =
            std::min(result.runner_up_disagreement, disagreements[k] / scale);
    }
  }
  result.association_seconds = Since(phase);
  if (!result.association.ok && !candidates.empty() && options.upright) {
    result.error = "feature association failed: none of " + std::to_string(candidates.size()) +
                   " candidate placements is within " +
                   std::to_string(static_cast<int>(options.upright->max_tilt_deg)) +
                   " degrees of upright";
    return result;
  }
  if (!result.association.ok) {
    result.error = "feature association failed: template has " +
                   std::to_string(model.features.num_terminals()) + " terminals and " +
                   std::to_string(model.features.num_junctions()) + " junctions, target " +
                   std::to_string(result.target_features.num_terminals()) + " and " +
                   std::to_string(result.target_features.num_junctions());
    return result;
  }
  const Similarity to_target = result.association.from_to;
  const Similarity to_template = to_target.Inverse();

  // Embedded deformation in the template's normalised frame, pulling each matched template
  // terminal to its partner brought back by the inverse similarity. Measured on the
  // benchmark: adding the junctions, or points along the skeleton paths between terminals,
  // made the result worse, because a mean-curvature-flow skeleton and a level-set skeleton
  // place junctions and limb ends differently; junctions still help the association.
  phase = std::chrono::steady_clock::now();
  std::vector<PointConstraint> constraints;
  for (const auto& [i, j] : result.association.terminals) {
    constraints.push_back(FeatureConstraint(model.features.terminals.col(i),
                                            to_template(result.target_features.terminals.col(j)),
                                            model.terminal_weights, i));
  }
  result.state = DeformationState::Identity(model.graph.num_nodes());
  result.deformation =
      SolveEmbeddedDeformation(model.graph, constraints, options.deformation, &result.state);
  result.deformation_seconds = Since(phase);
  if (!result.deformation.usable) {
    result.error = "embedded deformation failed: " + result.deformation.message;
    return result;
  }
  const Eigen::Matrix3Xd posed =
      DeformPoints(model.graph, model.vertex_weights, model.V, result.state);

  // Back to the target's frame.
  result.template_to_target = Similarity{to_target.scale * model.size, to_target.R, to_target.t};
  result.mesh.F = model.mesh.F;
  result.mesh.V.resize(3, posed.cols());
  for (Eigen::Index i = 0; i < posed.cols(); ++i) result.mesh.V.col(i) = to_target(posed.col(i));
  result.mesh.N = io::VertexNormals(result.mesh);
  result.ok = true;
  result.total_seconds = Since(start);
  return result;
}

}  // namespace vb::morph
