#include "morph/coarse_alignment.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <string>

#include "geometry/mesh_measures.h"
#include "geometry/principal_axes.h"
#include "io/error.h"
#include "morph/cloud_normals.h"
#include "morph/limb_turn.h"
#include "morph/order_statistic.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// How badly the template, placed by `fit`, and the target disagree as surfaces: the mean of
// closest-point distances both ways between a few hundred samples of each. A target sample's
// nearest placed template sample is looked up in the template's frame (@p template_index over
// @p template_samples), where `fit` keeps which sample is nearest up to rounding (a near tie
// may go to the other), so nothing is built per placement.
double SurfaceDisagreement(const Eigen::Matrix3Xd& template_samples,
                           const PointIndex& template_index, const Eigen::Matrix3Xd& target_samples,
                           const PointIndex& target_index, const Eigen::Matrix3Xd& target,
                           const Similarity& fit) {
  double sum = 0.0;
  for (Eigen::Index i = 0; i < template_samples.cols(); ++i) {
    const Eigen::Vector3d placed = fit(template_samples.col(i));
    sum += (target.col(target_index.Nearest(placed)) - placed).norm();
  }
  const Similarity back = fit.Inverse();
  for (Eigen::Index i = 0; i < target_samples.cols(); ++i) {
    const int nearest = template_index.Nearest(back(target_samples.col(i)));
    sum += (fit(template_samples.col(nearest)) - target_samples.col(i)).norm();
  }
  return sum / static_cast<double>(template_samples.cols() + target_samples.cols());
}

// Rounds of closest-point similarity fitting (Umeyama with scale) from `fit`, each on the
// 70 % of template samples nearest the target, so regions the target lacks do not pull.
Similarity RefineSimilarity(const Eigen::Matrix3Xd& template_samples,
                            const PointIndex& target_index, const Eigen::Matrix3Xd& target,
                            Similarity fit, int iterations) {
  const Eigen::Index n = template_samples.cols();
  Eigen::Matrix3Xd placed(3, n), matched(3, n), src(3, n), dst(3, n);
  std::vector<double> d(static_cast<std::size_t>(n)), sorted;
  for (int it = 0; it < iterations; ++it) {
    for (Eigen::Index i = 0; i < n; ++i) {
      placed.col(i) = fit(template_samples.col(i));
      matched.col(i) = target.col(target_index.Nearest(placed.col(i)));
      d[static_cast<std::size_t>(i)] = (matched.col(i) - placed.col(i)).norm();
    }
    sorted = d;
    const double limit = SelectQuantile(sorted, 0.7);
    Eigen::Index used = 0;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (d[static_cast<std::size_t>(i)] > limit) continue;
      src.col(used) = template_samples.col(i);
      dst.col(used++) = matched.col(i);
    }
    fit = Similarity::FromUmeyama(Eigen::umeyama(src.leftCols(used), dst.leftCols(used), true));
  }
  return fit;
}

// Each column of @p points moved by @p fit.
Eigen::Matrix3Xd Apply(const Similarity& fit, const Eigen::Matrix3Xd& points) {
  Eigen::Matrix3Xd out(3, points.cols());
  for (Eigen::Index i = 0; i < points.cols(); ++i) out.col(i) = fit(points.col(i));
  return out;
}

// @p placement after a half turn of the template about its longest principal axis (of
// @p template_samples) and, for @p count 2, about its shortest, each about the samples' mean,
// which stays where @p placement puts it.
std::vector<Similarity> HalfTurns(const Similarity& placement,
                                  const Eigen::Matrix3Xd& template_samples, int count) {
  const geometry::PrincipalAxes principal = geometry::FitPrincipalAxes(template_samples);
  const Eigen::Vector3d& mean = principal.mean;
  std::vector<Similarity> out;
  for (int k = 0; k < std::min(count, 2); ++k) {
    Similarity turned = placement;
    turned.R =
        placement.R *
        Eigen::AngleAxisd(std::numbers::pi, principal.axes.col(k == 0 ? 2 : 0)).toRotationMatrix();
    turned.t = placement(mean) - turned.scale * (turned.R * mean);
    out.push_back(turned);
  }
  return out;
}

// Similarities laying the principal axes of @p from on those of @p to, one per proper
// rotation of the cube (the axes' order and signs are not telling for a bent shape), scaled
// by the ratio of the spreads.
std::vector<Similarity> PrincipalFrameCandidates(const Eigen::Matrix3Xd& from,
                                                 const Eigen::Matrix3Xd& to) {
  auto frame = [](const Eigen::Matrix3Xd& p, Eigen::Vector3d* mean, double* spread) {
    *mean = p.rowwise().mean();
    const Eigen::Matrix3Xd centred = p.colwise() - *mean;
    const Eigen::Matrix3d covariance =
        centred * centred.transpose() / static_cast<double>(p.cols());
    *spread = std::sqrt(covariance.trace());
    Eigen::Matrix3d axes =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance).eigenvectors();
    if (axes.determinant() < 0) axes.col(0) = -axes.col(0);
    return axes;
  };
  Eigen::Vector3d from_mean, to_mean;
  double from_spread = 0, to_spread = 0;
  const Eigen::Matrix3d from_axes = frame(from, &from_mean, &from_spread);
  const Eigen::Matrix3d to_axes = frame(to, &to_mean, &to_spread);
  std::vector<Similarity> out;
  if (from_spread <= 0 || to_spread <= 0) return out;
  std::array<int, 3> axis{0, 1, 2};
  do {
    for (int signs = 0; signs < 8; ++signs) {
      Eigen::Matrix3d G = Eigen::Matrix3d::Zero();
      for (int r = 0; r < 3; ++r)
        G(r, axis[static_cast<std::size_t>(r)]) = (signs >> r & 1) ? -1 : 1;
      if (G.determinant() < 0) continue;
      Similarity s;
      s.R = to_axes * G * from_axes.transpose();
      s.scale = to_spread / from_spread;
      s.t = to_mean - s.scale * (s.R * from_mean);
      out.push_back(s);
    }
  } while (std::next_permutation(axis.begin(), axis.end()));
  return out;
}

// The posed template (normalised frame) brought to the target's frame by @p placement, then
// refitted from the target's side (RefitSimilarity), as the result's mesh; the placement the
// dense stage goes on from (association.from_to) and template_to_target include the refit. A
// refit turning the template to an orientation @p association does not accept (the upright
// prior) is dropped.
void Finish(const TemplateModel& model, const Similarity& placement, const Eigen::Matrix3Xd& posed,
            const Eigen::Matrix3Xd& target, const CoarseOptions& options,
            const AssociationOptions& association, WorkerPool* pool, CoarseResult* result) {
  Eigen::Matrix3Xd& V = result->mesh.V;
  V.resize(3, posed.cols());
  Similarity refit;
  if (options.refit.rounds > 0) {
    for (Eigen::Index i = 0; i < posed.cols(); ++i) V.col(i) = placement(posed.col(i));
    refit = RefitSimilarity(V, target, options.refit, pool);
  }
  if (!association.AcceptsOrientation(refit.R * placement.R)) refit = Similarity{};
  result->placement = placement;
  result->refit = refit;
  const Similarity to_target = Compose(refit, placement);
  result->association.from_to = to_target;
  result->template_to_target = Similarity{to_target.scale * model.size, to_target.R, to_target.t};
  for (Eigen::Index i = 0; i < V.cols(); ++i) V.col(i) = to_target(posed.col(i));
  result->mesh.F = model.mesh.F;
  result->mesh.N = geometry::VertexNormals(result->mesh);
  result->ok = true;
}

Eigen::Matrix3Xd EveryNth(const Eigen::Matrix3Xd& points, int wanted) {
  const Eigen::Index step = std::max<Eigen::Index>(1, points.cols() / wanted);
  Eigen::Matrix3Xd out(3, (points.cols() + step - 1) / step);
  for (Eigen::Index i = 0, k = 0; i < points.cols(); i += step, ++k) out.col(k) = points.col(i);
  return out;
}

// Whether @p given holds a normal for every point of @p target (else the posture fit
// estimates its own).
bool HasNormals(const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd* given) {
  return given != nullptr && given->cols() == target.cols();
}

// The target's normals for the posture fit's pairing (ArticulationOptions::
// max_normal_angle_deg): the given ones made unit (zero, "no direction known", where one has
// no length or is not finite), else principal-axis normals of @p neighbours points over
// @p passes (EstimateNormals), of either sign.
Eigen::Matrix3Xd PostureNormals(const Eigen::Matrix3Xd& target, const PointIndex& index,
                                const Eigen::Matrix3Xd* given, int neighbours, int passes,
                                WorkerPool* pool) {
  if (HasNormals(target, given)) {
    Eigen::Matrix3Xd out(3, given->cols());
    for (Eigen::Index i = 0; i < given->cols(); ++i) {
      const double length = given->col(i).norm();
      out.col(i) = std::isfinite(length) && length > 1e-12 ? Eigen::Vector3d(given->col(i) / length)
                                                           : Eigen::Vector3d::Zero();
    }
    return out;
  }
  return EstimateNormals(target, index, std::max(3, neighbours), passes, Eigen::Matrix3Xd(3, 0),
                         pool);
}

}  // namespace

CoarseResult AlignCoarse(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                         const CoarseOptions& options, WorkerPool* pool,
                         const PointIndex* given_index, const Eigen::Matrix3Xd* target_normals,
                         int fit_normal_passes) {
  VB_DEMAND(fit_normal_passes >= 1);
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
  const double target_size = geometry::BoundingBoxDiagonal(target);
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
  AssociationOptions association = options.association;
  if (options.upright.enabled) {
    association.from_up = options.upright.template_up.normalized();
    association.to_up = options.upright.target_up.normalized();
    association.min_cos_up = std::cos(options.upright.max_tilt_deg * std::numbers::pi / 180.0);
  }
  std::vector<Association> candidates =
      AssociateFeatureNodes(model.features, result.target_features, association);
  // A pairing whose nodes all lie in one spot has no usable fit to place the template with.
  std::erase_if(candidates, [](const Association& a) { return !a.from_to.Usable(); });
  const std::size_t skeleton_candidates = candidates.size();
  const Eigen::Matrix3Xd template_samples = EveryNth(model.V, options.verification_samples);
  const PointIndex template_index(template_samples);
  const Eigen::Matrix3Xd target_samples = EveryNth(target, options.verification_samples);
  VB_DEMAND(given_index == nullptr || given_index->size() == target.cols());
  std::unique_ptr<PointIndex> own_index;
  if (given_index == nullptr) own_index = std::make_unique<PointIndex>(target);
  const PointIndex& target_index = given_index != nullptr ? *given_index : *own_index;
  // Every skeleton candidate already keeps within the upright prior's tilt (the search drops
  // the others); refined fits and frame candidates are checked below.
  // Scoring and refining are independent per placement: each on one of the pool's threads,
  // each writing only its own entry.
  std::vector<double> disagreements(candidates.size());
  ForEach(pool, static_cast<int>(candidates.size()), [&](int k) {
    disagreements[static_cast<std::size_t>(k)] =
        SurfaceDisagreement(template_samples, template_index, target_samples, target_index, target,
                            candidates[static_cast<std::size_t>(k)].from_to);
  });
  // The skeleton fits are only as good as the skeletons: the best few placements are
  // refined against the surfaces before the final choice (docs/decisions.md: placed clouds
  // at sigma 16 mm 87 -> 97 %).
  if (options.refine_iterations > 0) {
    std::vector<std::size_t> order(candidates.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return disagreements[a] < disagreements[b]; });
    const std::size_t count =
        std::min(order.size(), static_cast<std::size_t>(std::max(0, options.refine_candidates)));
    ForEach(pool, static_cast<int>(count), [&](int r) {
      const std::size_t k = order[static_cast<std::size_t>(r)];
      const Similarity refined = RefineSimilarity(template_samples, target_index, target,
                                                  candidates[k].from_to, options.refine_iterations);
      if (!refined.Usable() || !association.AcceptsOrientation(refined.R)) return;
      const double d = SurfaceDisagreement(template_samples, template_index, target_samples,
                                           target_index, target, refined);
      if (d < disagreements[k]) {
        candidates[k].from_to = refined;
        disagreements[k] = d;
      }
    });
  }
  // Each of @p starts refined, and its disagreement with the target: infinite for a refined
  // placement that is unusable or tilted past the prior (not kept).
  const auto refine_all = [&](const std::vector<Similarity>& starts,
                              std::vector<Similarity>* refined, std::vector<double>* disagreement) {
    refined->assign(starts.size(), Similarity{});
    disagreement->assign(starts.size(), std::numeric_limits<double>::infinity());
    ForEach(pool, static_cast<int>(starts.size()), [&](int f) {
      const auto k = static_cast<std::size_t>(f);
      (*refined)[k] = RefineSimilarity(template_samples, target_index, target, starts[k],
                                       options.refine_iterations);
      if (!(*refined)[k].Usable() || !association.AcceptsOrientation((*refined)[k].R)) return;
      (*disagreement)[k] = SurfaceDisagreement(template_samples, template_index, target_samples,
                                               target_index, target, (*refined)[k]);
    });
  };
  // A candidate placed by from_to, with the skeleton search's counts for the report.
  const auto placed = [&](const Similarity& from_to) {
    Association candidate;
    candidate.ok = true;
    if (skeleton_candidates > 0) {
      candidate.candidates = candidates.front().candidates;
      candidate.pruned = candidates.front().pruned;
    }
    candidate.from_to = from_to;
    return candidate;
  };
  // Placements that do not come from the skeletons: the template's principal axes laid on
  // the target's in each of the 24 ways a proper rotation can, then refined the same way.
  // When the skeletons disagree too much for any pairing to be right (a shape with many
  // alike limbs, a limb lost to occlusion), one of these is.
  if (options.frame_candidates && options.refine_iterations > 0) {
    std::vector<Similarity> starts = PrincipalFrameCandidates(template_samples, target_samples);
    std::erase_if(starts,
                  [&](const Similarity& s) { return !association.AcceptsOrientation(s.R); });
    std::vector<Similarity> refined;
    std::vector<double> refined_disagreement;
    refine_all(starts, &refined, &refined_disagreement);
    for (std::size_t k = 0; k < starts.size(); ++k) {
      if (std::isinf(refined_disagreement[k])) continue;
      candidates.push_back(placed(refined[k]));
      disagreements.push_back(refined_disagreement[k]);
    }
  }
  // The posture fit on the best distinct placements: the true one is the one whose limbs,
  // once turned into the target's pose, cover the target best. Rigid disagreement alone
  // cannot tell a body facing forward from one facing back when the limbs differ.
  std::vector<double> articulated(candidates.size(), std::numeric_limits<double>::infinity());
  std::vector<DeformationState> articulated_states(candidates.size());
  Eigen::Matrix3Xd posture_normals;  // for the posture fits' pairing; none: not used
  const auto posture_normals_or_none = [&]() {
    return posture_normals.cols() > 0 ? &posture_normals : nullptr;
  };
  if (options.articulated_candidates > 0 && !candidates.empty()) {
    std::vector<std::size_t> order(candidates.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return disagreements[a] < disagreements[b]; });
    const double cos_distinct = std::cos(options.distinct_angle_deg * std::numbers::pi / 180.0);
    std::vector<std::size_t> picked;
    // Whether rotation R is turned more than distinct_angle_deg from every picked placement.
    const auto distinct = [&](const Eigen::Matrix3d& R) {
      return std::all_of(picked.begin(), picked.end(), [&](std::size_t p) {
        const Eigen::Matrix3d relative = R * candidates[p].from_to.R.transpose();
        return 0.5 * (relative.trace() - 1.0) < cos_distinct;
      });
    };
    for (std::size_t k : order) {
      if (static_cast<int>(picked.size()) >= options.articulated_candidates) break;
      if (distinct(candidates[k].from_to.R)) picked.push_back(k);
    }
    // The best placement turned half round about the template's longest and shortest axes:
    // the turns a placement confuses (front for back, upside down), and when the pose changed
    // far, the ones that none of the placements above may be near (docs/decisions.md).
    if (options.turned_candidates > 0 && !picked.empty()) {
      const std::vector<Similarity> turns =
          HalfTurns(candidates[picked.front()].from_to, template_samples, options.turned_candidates);
      std::vector<Similarity> refined;
      std::vector<double> refined_disagreement;
      refine_all(turns, &refined, &refined_disagreement);
      for (std::size_t k = 0; k < turns.size(); ++k) {
        if (std::isinf(refined_disagreement[k]) || !distinct(refined[k].R)) continue;
        candidates.push_back(placed(refined[k]));
        disagreements.push_back(refined_disagreement[k]);
        articulated.push_back(std::numeric_limits<double>::infinity());
        articulated_states.emplace_back();
        picked.push_back(candidates.size() - 1);
      }
    }
    if (options.articulation.max_normal_angle_deg < 90.0) {
      posture_normals = PostureNormals(target, target_index, target_normals,
                                       options.articulation.normal_neighbours, 1, pool);
    }
    ArticulationOptions choice = options.articulation;
    choice.rounds = std::min(choice.rounds, options.choice_rounds);
    choice.weigh_by_asymmetry = options.choice_by_asymmetry;
    // Branch pulls draw a turned placement's limbs onto branches as readily as the right
    // one's, so the choice is made without them (docs/decisions.md).
    choice.branch_weight = 0.0;
    // The fits are independent: each on one of the pool's threads.
    const auto fit_candidate = [&](int p) {
      const std::size_t k = picked[static_cast<std::size_t>(p)];
      ArticulationResult fit =
          ArticulateTemplate(model, target, target_index, result.target_features.terminals,
                             DeformationState::Identity(model.graph.num_nodes()), choice,
                             candidates[k].from_to, nullptr, posture_normals_or_none());
      if (!fit.ok) return;
      articulated[k] = fit.disagreement;
      articulated_states[k] = std::move(fit.state);
    };
    ForEach(pool, static_cast<int>(picked.size()), fit_candidate);
  }
  const bool use_articulated = std::any_of(articulated.begin(), articulated.end(),
                                           [](double d) { return std::isfinite(d); });
  std::size_t chosen = 0;
  if (!candidates.empty()) {
    const std::vector<double>& score = use_articulated ? articulated : disagreements;
    chosen = static_cast<std::size_t>(std::min_element(score.begin(), score.end()) - score.begin());
    if (use_articulated) {
      // Compared on the articulated scores, template sizes: disagreements are rescaled below.
      for (std::size_t k = 0; k < candidates.size(); ++k)
        disagreements[k] = articulated[k] * candidates[chosen].from_to.scale;
    }
    result.association = candidates[chosen];
    // Set again by Finish; here as well so that a stage failing later still reports it.
    result.placement = candidates[chosen].from_to;
    result.placed_by_skeletons = chosen < skeleton_candidates;
    const double scale = result.association.from_to.scale;  // target units per template size
    result.disagreement = disagreements[chosen] / scale;
    result.choice_disagreement = result.disagreement;
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
    result.choices.reserve(candidates.size());
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      if (std::isfinite(disagreements[k]))
        result.choices.push_back({candidates[k].from_to.R, disagreements[k] / scale});
    }
  }
  // The chosen placement may come from a pairing with one pair wrong (a neck taken for a
  // fore leg) that still overlaps the surfaces best. The pairs the deformation pulls on are
  // therefore taken again from the placement itself: mutual nearest features of each kind.
  if (result.association.ok && options.repair_radius > 0) {
    const double radius = options.repair_radius * result.association.from_to.scale;
    Association repaired = result.association;
    // The pairing the chosen placement implies.
    const Similarity& fit = result.association.from_to;
    repaired.terminals = MutualNearestPairs(Apply(fit, model.features.terminals),
                                            result.target_features.terminals, radius);
    repaired.junctions = MutualNearestPairs(Apply(fit, model.features.junctions),
                                            result.target_features.junctions, radius);
    const bool from_frame = result.association.terminals.empty();  // a frame candidate
    if (from_frame || (repaired.terminals.size() >= 2 &&
                       repaired.terminals.size() + repaired.junctions.size() >= 3)) {
      result.association.terminals = std::move(repaired.terminals);
      result.association.junctions = std::move(repaired.junctions);
    }
  }
  result.association_seconds = Since(phase);
  if (!result.association.ok && options.upright.enabled) {
    result.error =
        "feature association failed: no placement of the skeletons' features is within " +
        std::to_string(static_cast<int>(options.upright.max_tilt_deg)) + " degrees of upright";
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

  if (use_articulated && result.association.ok) {
    // Go on from the chosen candidate's pose for the remaining rounds.
    phase = std::chrono::steady_clock::now();
    // From the choice on, normals that average the noise away: one pass leaves a noisy
    // cloud's normals near random, and the pairing drops pairs by them (docs/decisions.md:
    // averaged for the choice as well, they flipped as many placements as they righted).
    if (posture_normals.cols() > 0 && !HasNormals(target, target_normals) &&
        fit_normal_passes > 1) {
      posture_normals =
          PostureNormals(target, target_index, nullptr, options.articulation.normal_neighbours,
                         fit_normal_passes, pool);
      result.posture_normal_passes = fit_normal_passes;
    }
    ArticulationOptions rest = options.articulation;
    rest.rounds = std::max(0, options.articulation.rounds - options.choice_rounds);
    rest.stiffness_start =
        std::max(options.articulation.min_stiffness,
                 options.articulation.stiffness_start *
                     std::pow(options.articulation.stiffness_decay, options.choice_rounds));
    const bool turn_limbs = options.articulation.limb_turn_gain > 0;
    const BranchGuide guide = (rest.branch_weight > 0 && rest.rounds > 0) || turn_limbs
                                  ? MakeBranchGuide(model, skeleton, result.target_features)
                                  : BranchGuide{};
    ArticulationResult fit = ArticulateTemplate(
        model, target, target_index, result.target_features.terminals, articulated_states[chosen],
        rest, to_target, &guide, posture_normals_or_none());
    int iterations = options.choice_rounds + fit.rounds;
    const DeformationState first_state = fit.state;
    // Limbs that turned too far for closest points: the fit again from them turned onto the
    // target's limbs (TurnLimbs), from them swung about their roots to where they explain the
    // target best (SwingLimbs), and swung about points out along them as well where that
    // explains it better still, and from limbs turned onto target limbs the first fit left
    // bare (ReclaimLimbs); the best kept when it covers the target clearly better than the
    // first. The swing's score and the fit's disagreement do not always agree on the pivot,
    // so both swings are fitted.
    if (turn_limbs) {
      std::array<int, 4> moved{0, 0, 0, 0};
      int beyond_roots = 0;
      RootSwing about_roots;
      std::array<DeformationState, 4> starts;
      starts[0] = TurnLimbs(model, guide, target, target_index, to_target, options.articulation,
                            &moved[0], &first_state);
      starts[2] = SwingLimbs(model, guide, target, target_index, to_target, first_state,
                             options.articulation, &moved[2], pool, &beyond_roots, &about_roots);
      starts[1] = std::move(about_roots.state);
      moved[1] = about_roots.swung;
      // No limb moved far about a pivot beyond its root: that start differs from the swing
      // about the roots by nudges the fit makes itself, if at all.
      if (beyond_roots == 0) moved[2] = 0;
      starts[3] = ReclaimLimbs(model, guide, target, to_target, first_state, options.articulation,
                               &moved[3]);
      // The fits are independent: each on one of the pool's threads; on a tie the earlier
      // start is preferred, whatever the threads.
      std::array<ArticulationResult, 4> again;
      ForEach(pool, static_cast<int>(again.size()), [&](int k) {
        const auto s = static_cast<std::size_t>(k);
        if (moved[s] == 0) return;
        again[s] = ArticulateTemplate(model, target, target_index, result.target_features.terminals,
                                      starts[s], options.articulation, to_target, &guide,
                                      posture_normals_or_none());
      });
      const double limit = options.articulation.limb_turn_gain * fit.disagreement;
      for (std::size_t k = 0; k < again.size(); ++k) {
        if (!again[k].ok || !(again[k].disagreement < limit) ||
            !(again[k].disagreement < fit.disagreement))
          continue;
        result.limbs_turned = moved[k];
        iterations = again[k].rounds;
        fit = std::move(again[k]);
      }
    }
    result.state = std::move(fit.state);
    result.disagreement = fit.disagreement;
    result.deformation.usable = true;
    result.deformation.iterations = iterations;
    result.deformation.message =
        result.limbs_turned > 0
            ? "posture fit, " + std::to_string(result.limbs_turned) + " limbs turned or swung"
            : std::string("posture fit");
    result.deformation_seconds = Since(phase);
    Finish(model, to_target, DeformPoints(model.graph, model.vertex_weights, model.V, result.state),
           target, options, association, pool, &result);
    result.total_seconds = Since(start);
    return result;
  }

  // Embedded deformation in the template's normalised frame, pulling each matched template
  // terminal to its partner brought back by the inverse similarity. Measured on the
  // benchmark: adding the junctions, or points along the skeleton paths between terminals,
  // made the result worse, because a mean-curvature-flow skeleton and a level-set skeleton
  // place junctions and limb ends differently; junctions still help the association.
  phase = std::chrono::steady_clock::now();
  std::vector<PointConstraint> constraints;
  for (const auto& [i, j] : result.association.terminals) {
    // The data term of one template feature node, in the template's normalised frame.
    constraints.push_back(ConstrainPoint(model.terminal_weights, i, model.features.terminals.col(i),
                                         to_template(result.target_features.terminals.col(j))));
  }
  result.state = DeformationState::Identity(model.graph.num_nodes());
  result.deformation =
      SolveEmbeddedDeformation(model.graph, constraints, options.deformation, &result.state);
  result.deformation_seconds = Since(phase);
  if (!result.deformation.usable) {
    result.error = "embedded deformation failed: " + result.deformation.message;
    return result;
  }
  Eigen::Matrix3Xd posed = DeformPoints(model.graph, model.vertex_weights, model.V, result.state);
  // The pairs it pulls on may be wrong, or right but placed differently by the two
  // skeletonisers; the deformation is kept only if it brings the surfaces closer than the
  // rigid placement did.
  if (options.check_deformation && !constraints.empty()) {
    const Eigen::Matrix3Xd posed_samples = EveryNth(posed, options.verification_samples);
    const double deformed = SurfaceDisagreement(posed_samples, PointIndex(posed_samples),
                                                target_samples, target_index, target, to_target);
    result.deformation_kept = deformed <= result.disagreement * to_target.scale;
    if (!result.deformation_kept) {
      result.state = DeformationState::Identity(model.graph.num_nodes());
      posed = model.V;
    }
  }

  Finish(model, to_target, posed, target, options, association, pool, &result);
  result.total_seconds = Since(start);
  return result;
}

}  // namespace vb::morph
