#include "morph/articulated_fit.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>

#include "geometry/principal_axes.h"
#include "io/error.h"
#include "morph/order_statistic.h"

namespace vb::morph {
namespace {

// The value below which the nearest @p keep_fraction of the finite values of @p d lie (an
// infinite one is a sample without a partner).
double KeepLimit(std::vector<double> d, double keep_fraction) {
  std::erase(d, std::numeric_limits<double>::infinity());
  if (d.empty()) return 0.0;
  return SelectQuantile(d, keep_fraction);
}

double TrimmedMean(std::vector<double> d, double keep_fraction) {
  if (d.empty()) return 0.0;
  const double limit = KeepLimit(d, keep_fraction);
  double sum = 0.0;
  int count = 0;
  for (double x : d) {
    if (x > limit) continue;
    sum += x;
    ++count;
  }
  return count > 0 ? sum / count : 0.0;
}

// Whether two normals of either sign are within the angle whose cosine is @p min_cos; a zero
// normal (no direction known) is compatible with any.
bool FacingAlike(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double min_cos) {
  const double scale = a.squaredNorm() * b.squaredNorm();
  return scale == 0.0 || std::abs(a.dot(b)) >= min_cos * std::sqrt(scale);
}

// The nearest of the @p candidates points of @p index nearest to @p q whose normal faces as
// @p normal does (FacingAlike); -1 when none of them does.
int NearestFacingAlike(const PointIndex& index, const Eigen::Matrix3Xd& normals,
                       const Eigen::Vector3d& q, const Eigen::Vector3d& normal, int candidates,
                       double min_cos, std::vector<int>* found, std::vector<double>* distances) {
  index.Nearest(q, candidates, found, distances);
  for (int j : *found)
    if (FacingAlike(normals.col(j), normal, min_cos)) return j;
  return -1;
}

}  // namespace

std::vector<int> Spread(Eigen::Index n, int wanted) {
  std::vector<int> out;
  const Eigen::Index step = std::max<Eigen::Index>(1, n / std::max(1, wanted));
  out.reserve(static_cast<std::size_t>(std::max<Eigen::Index>(0, (n + step - 1) / step)));
  for (Eigen::Index i = 0; i < n; i += step) out.push_back(static_cast<int>(i));
  return out;
}

TemplateSamples SampleTemplate(const TemplateModel& model, int wanted) {
  TemplateSamples out;
  out.ids = Spread(model.V.cols(), wanted);
  const auto n = static_cast<Eigen::Index>(out.ids.size());
  out.rest = model.V(Eigen::all, out.ids);
  out.weights.nodes = model.vertex_weights.nodes(Eigen::all, out.ids);
  out.weights.weights = model.vertex_weights.weights(Eigen::all, out.ids);
  VB_DEMAND(out.rest.cols() == n);
  return out;
}

std::vector<std::pair<int, int>> PairBranches(const BranchGuide& guide,
                                              const Eigen::Matrix3Xd& posed,
                                              const Eigen::Matrix3Xd& target, double scale,
                                              double along, const ArticulationOptions& options) {
  const int na = guide.num_template_branches(), nb = guide.num_target_branches();
  const int out = BranchGuide::SampleAt(along);
  Eigen::MatrixXd cost = Eigen::MatrixXd::Constant(na, nb, std::numeric_limits<double>::infinity());
  for (int a = 0; a < na; ++a) {
    for (int b = 0; b < nb; ++b) {
      const double la = guide.limbs->length[static_cast<std::size_t>(a)];
      const double lb = guide.target_length[static_cast<std::size_t>(b)] / scale;
      if (!(la > 0 && lb > 0) || std::max(la, lb) > options.branch_max_ratio * std::min(la, lb))
        continue;
      const double c =
          (posed.col(BranchGuide::Column(a, 0)) - target.col(BranchGuide::Column(b, 0))).norm() +
          (posed.col(BranchGuide::Column(a, out)) - target.col(BranchGuide::Column(b, out))).norm();
      if (c <= options.branch_radius) cost(a, b) = c;
    }
  }
  std::vector<std::pair<int, int>> pairs;
  for (int a = 0; a < na; ++a) {
    Eigen::Index b = 0, back = 0;
    if (nb == 0 || !std::isfinite(cost.row(a).minCoeff(&b))) continue;
    cost.col(b).minCoeff(&back);
    if (back == a) pairs.emplace_back(a, static_cast<int>(b));
  }
  return pairs;
}

Eigen::Matrix3Xd TargetBranchesIn(const BranchGuide& guide, const Similarity& to_template) {
  Eigen::Matrix3Xd out(3, guide.target_points.cols());
  for (Eigen::Index k = 0; k < out.cols(); ++k)
    out.col(k) = to_template(guide.target_points.col(k));
  return out;
}

BranchGuide MakeBranchGuide(const TemplateModel& model, const SkeletonGraph& target_skeleton,
                            const FeatureNodes& target_features) {
  BranchGuide guide;
  guide.limbs = &model.limbs;
  const std::vector<SkeletonBranch> theirs = TerminalBranches(target_skeleton, target_features);
  constexpr int kSamples = BranchGuide::kSamples;
  guide.target_points.resize(3, static_cast<Eigen::Index>(theirs.size()) * kSamples);
  for (std::size_t b = 0; b < theirs.size(); ++b) {
    guide.target_length.push_back(theirs[b].length());
    std::vector<int>& support = guide.target_support.emplace_back();
    for (std::size_t k = 1; k < theirs[b].nodes.size(); ++k) {
      const auto node = static_cast<std::size_t>(theirs[b].nodes[k]);
      if (node < target_skeleton.support.size())
        support.insert(support.end(), target_skeleton.support[node].begin(),
                       target_skeleton.support[node].end());
    }
    for (int k = 0; k < kSamples; ++k) {
      guide.target_points.col(BranchGuide::Column(static_cast<int>(b), k)) =
          PointAlong(target_skeleton, theirs[b], static_cast<double>(k) / (kSamples - 1));
    }
  }
  return guide;
}

std::vector<std::pair<int, int>> MutualNearestPairs(const Eigen::Matrix3Xd& a,
                                                    const Eigen::Matrix3Xd& b, double radius) {
  std::vector<std::pair<int, int>> pairs;
  if (a.cols() == 0 || b.cols() == 0) return pairs;
  for (Eigen::Index i = 0; i < a.cols(); ++i) {
    Eigen::Index j = 0, back = 0;
    const double d2 = (b.colwise() - a.col(i)).colwise().squaredNorm().minCoeff(&j);
    (a.colwise() - b.col(j)).colwise().squaredNorm().minCoeff(&back);
    if (back == i && d2 <= radius * radius)
      pairs.emplace_back(static_cast<int>(i), static_cast<int>(j));
  }
  return pairs;
}

namespace {

// The distance from each column of @p from to the nearest point @p to holds, and, given
// @p partners, that point's index.
std::vector<double> NearestDistances(const Eigen::Matrix3Xd& from, const PointIndex& to,
                                     std::vector<int>* partners = nullptr) {
  std::vector<double> out(static_cast<std::size_t>(from.cols()));
  if (partners != nullptr) partners->resize(out.size());
  std::vector<int> k;
  std::vector<double> d2;
  for (Eigen::Index i = 0; i < from.cols(); ++i) {
    to.Nearest(from.col(i), 1, &k, &d2);
    out[static_cast<std::size_t>(i)] = std::sqrt(d2.front());
    if (partners != nullptr) (*partners)[static_cast<std::size_t>(i)] = k.front();
  }
  return out;
}

}  // namespace

double TrimmedDisagreement(const Eigen::Matrix3Xd& a, const PointIndex& a_index,
                           const Eigen::Matrix3Xd& b_samples, const PointIndex& b_index,
                           double keep_fraction) {
  VB_DEMAND(a_index.size() > 0 && b_index.size() > 0);
  std::vector<double> forward = NearestDistances(a, b_index);
  std::vector<double> backward = NearestDistances(b_samples, a_index);
  return 0.5 * (TrimmedMean(std::move(forward), keep_fraction) +
                TrimmedMean(std::move(backward), keep_fraction));
}

std::vector<double> HalfTurnAsymmetry(const Eigen::Matrix3Xd& samples) {
  VB_DEMAND(samples.cols() > 0);
  const geometry::PrincipalAxes principal = geometry::FitPrincipalAxes(samples);
  const Eigen::Vector3d& mean = principal.mean;
  const Eigen::Matrix3d half =
      Eigen::AngleAxisd(std::numbers::pi, principal.axes.col(2)).toRotationMatrix();
  const PointIndex index(samples);
  std::vector<double> out(static_cast<std::size_t>(samples.cols()));
  for (Eigen::Index i = 0; i < samples.cols(); ++i) {
    const Eigen::Vector3d turned = mean + half * (samples.col(i) - mean);
    out[static_cast<std::size_t>(i)] = (samples.col(index.Nearest(turned)) - turned).norm();
  }
  return out;
}

double WeightedTrimmedDisagreement(const Eigen::Matrix3Xd& a, const PointIndex& a_index,
                                   const std::vector<double>& a_weights,
                                   const Eigen::Matrix3Xd& b_samples, const PointIndex& b_index,
                                   double keep_fraction) {
  VB_DEMAND(a_index.size() > 0 && b_index.size() > 0);
  VB_DEMAND(a_weights.size() == static_cast<std::size_t>(a.cols()));
  const std::vector<double> forward = NearestDistances(a, b_index);
  std::vector<int> backward_partner;
  const std::vector<double> backward = NearestDistances(b_samples, a_index, &backward_partner);
  // The kept distances' weighted mean; their plain mean when the kept weights sum to zero.
  const auto weighted_mean = [&](const std::vector<double>& d, auto weight_of) {
    if (d.empty()) return 0.0;
    const double limit = KeepLimit(d, keep_fraction);
    double sum = 0.0, weights = 0.0, plain = 0.0;
    int count = 0;
    for (std::size_t i = 0; i < d.size(); ++i) {
      if (d[i] > limit) continue;
      const double w = weight_of(i);
      VB_DEMAND(w >= 0.0);
      sum += w * d[i];
      weights += w;
      plain += d[i];
      ++count;
    }
    if (weights > 0.0) return sum / weights;
    return count > 0 ? plain / count : 0.0;
  };
  return 0.5 * (weighted_mean(forward, [&](std::size_t i) { return a_weights[i]; }) +
                weighted_mean(backward, [&](std::size_t i) {
                  return a_weights[static_cast<std::size_t>(backward_partner[i])];
                }));
}

ArticulationResult ArticulateTemplate(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                                      const PointIndex& target_index,
                                      const Eigen::Matrix3Xd& target_terminals,
                                      const DeformationState& start,
                                      const ArticulationOptions& options,
                                      const Similarity& placement, const BranchGuide* guide,
                                      const Eigen::Matrix3Xd* target_normals) {
  const auto begin = std::chrono::steady_clock::now();
  VB_DEMAND(target.cols() > 0 && target_index.size() == target.cols());
  VB_DEMAND(placement.Usable());
  const Similarity back = placement.Inverse();  // target frame -> template frame
  ArticulationResult result;
  result.state = start;

  // The template samples with their node weights, and the target samples.
  const TemplateSamples sampled = SampleTemplate(model, options.template_samples);
  const std::vector<int>& template_ids = sampled.ids;
  const Eigen::Matrix3Xd& rest = sampled.rest;
  const NodeWeights& weights = sampled.weights;
  const auto ns = static_cast<Eigen::Index>(template_ids.size());
  // The target samples in the target's frame (for the final disagreement) and in the
  // template's (for the fit).
  const std::vector<int> target_ids = Spread(target.cols(), options.target_samples);
  const Eigen::Matrix3Xd samples_there = target(Eigen::all, target_ids);
  Eigen::Matrix3Xd target_samples(3, samples_there.cols());
  for (Eigen::Index k = 0; k < samples_there.cols(); ++k)
    target_samples.col(k) = back(samples_there.col(k));

  // Normals, for pairs between surfaces facing alike: the template samples' at rest and the
  // target samples' in the template's frame.
  VB_DEMAND(target_normals == nullptr || target_normals->cols() == target.cols());
  const bool facing = target_normals != nullptr && options.max_normal_angle_deg < 90.0 &&
                      model.mesh.N.cols() == model.V.cols();
  const double min_cos = std::cos(options.max_normal_angle_deg * std::numbers::pi / 180.0);
  const int candidates = std::max(1, options.normal_candidates);
  Eigen::Matrix3Xd rest_normals, target_sample_normals;
  if (facing) {
    rest_normals = model.mesh.N(Eigen::all, template_ids);
    // Column by column: a product over an indexed view copies the view's indices for every
    // coefficient it evaluates.
    target_sample_normals.resize(3, static_cast<Eigen::Index>(target_ids.size()));
    for (std::size_t k = 0; k < target_ids.size(); ++k)
      target_sample_normals.col(static_cast<Eigen::Index>(k)) =
          placement.R.transpose() * target_normals->col(target_ids[k]);
  }

  Eigen::Matrix3Xd terminals(3, target_terminals.cols());  // template frame
  for (Eigen::Index t = 0; t < terminals.cols(); ++t)
    terminals.col(t) = back(target_terminals.col(t));

  // The target's branch samples in the template's frame.
  const bool use_branches = guide != nullptr && options.branch_weight > 0 &&
                            guide->num_template_branches() > 0 && guide->num_target_branches() > 0;
  const Eigen::Matrix3Xd branch_targets =
      use_branches ? TargetBranchesIn(*guide, back) : Eigen::Matrix3Xd();
  double branch_weight = options.branch_weight;

  std::vector<PointConstraint> constraints;
  std::vector<double> forward(static_cast<std::size_t>(ns));
  Eigen::Matrix3Xd forward_partner(3, ns);  // template frame
  std::vector<double> backward(target_ids.size());
  std::vector<int> backward_partner(target_ids.size());
  // The distance of a sample without a partner: left out of the trimming, never kept.
  constexpr double kUnpaired = std::numeric_limits<double>::infinity();
  std::vector<int> found;
  std::vector<double> found_distances;
  double stiffness = options.stiffness_start;
  DeformationScratch scratch;  // one for every round's solve
  for (int round = 0; round < options.rounds; ++round) {
    const Eigen::Matrix3Xd posed = DeformPoints(model.graph, weights, rest, result.state);
    const PointIndex posed_index(posed);
    const Eigen::Matrix3Xd posed_normals =
        facing ? DeformNormals(weights, rest_normals, result.state) : Eigen::Matrix3Xd();
    for (Eigen::Index i = 0; i < ns; ++i) {
      const Eigen::Vector3d there = placement(posed.col(i));
      const int j = facing ? NearestFacingAlike(target_index, *target_normals, there,
                                                placement.R * posed_normals.col(i), candidates,
                                                min_cos, &found, &found_distances)
                           : target_index.Nearest(there);
      if (j < 0) {
        forward[static_cast<std::size_t>(i)] = kUnpaired;
        continue;
      }
      forward_partner.col(i) = back(target.col(j));
      forward[static_cast<std::size_t>(i)] = (forward_partner.col(i) - posed.col(i)).norm();
    }
    for (Eigen::Index k = 0; k < target_samples.cols(); ++k) {
      const int i = facing ? NearestFacingAlike(posed_index, posed_normals, target_samples.col(k),
                                                target_sample_normals.col(k), candidates, min_cos,
                                                &found, &found_distances)
                           : posed_index.Nearest(target_samples.col(k));
      if (i < 0) {
        backward[static_cast<std::size_t>(k)] = kUnpaired;
        continue;
      }
      backward_partner[static_cast<std::size_t>(k)] = i;
      backward[static_cast<std::size_t>(k)] = (target_samples.col(k) - posed.col(i)).norm();
    }
    const double forward_limit = KeepLimit(forward, options.keep_fraction);
    const double backward_limit = KeepLimit(backward, options.target_keep_fraction);
    constraints.clear();
    for (Eigen::Index i = 0; i < ns; ++i) {
      const double d = forward[static_cast<std::size_t>(i)];
      if (d == kUnpaired || d > forward_limit) continue;
      constraints.push_back(ConstrainPoint(weights, i, rest.col(i), forward_partner.col(i)));
    }
    for (Eigen::Index k = 0; k < target_samples.cols(); ++k) {
      const double d = backward[static_cast<std::size_t>(k)];
      if (d == kUnpaired || d > backward_limit) continue;
      const int i = backward_partner[static_cast<std::size_t>(k)];
      constraints.push_back(ConstrainPoint(weights, i, rest.col(i), target_samples.col(k)));
    }
    if (constraints.empty()) break;
    const double per_pair =
        static_cast<double>(model.graph.num_nodes()) / static_cast<double>(constraints.size());
    for (PointConstraint& c : constraints) c.weight = per_pair;
    if (options.terminal_radius > 0 && options.terminal_weight > 0 &&
        terminals.cols() > 0 && model.features.num_terminals() > 0) {
      const Eigen::Matrix3Xd tips = DeformPoints(model.graph, model.terminal_weights,
                                                 model.features.terminals, result.state);
      for (const auto& [i, j] : MutualNearestPairs(tips, terminals, options.terminal_radius)) {
        PointConstraint c = ConstrainPoint(model.terminal_weights, i, model.features.terminals.col(i),
                                           terminals.col(j));
        c.weight = per_pair * options.terminal_weight;
        constraints.push_back(std::move(c));
      }
    }
    if (use_branches) {
      const Eigen::Matrix3Xd along =
          DeformPoints(model.graph, guide->limbs->weights, guide->limbs->rest, result.state);
      for (const auto& [a, b] :
           PairBranches(*guide, along, branch_targets, placement.scale, 0.75, options)) {
        const double la = guide->limbs->length[static_cast<std::size_t>(a)];
        const double lb = guide->target_length[static_cast<std::size_t>(b)] / placement.scale;
        const double shorter = std::min(la, lb);
        for (const double share : {0.5, 0.75, 1.0}) {
          const Eigen::Index from =
              BranchGuide::Column(a, BranchGuide::SampleAt(share * shorter / la));
          const Eigen::Index to =
              BranchGuide::Column(b, BranchGuide::SampleAt(share * shorter / lb));
          PointConstraint c = ConstrainPoint(guide->limbs->weights, from,
                                             guide->limbs->rest.col(from), branch_targets.col(to));
          c.weight = per_pair * branch_weight;
          constraints.push_back(std::move(c));
        }
      }
      branch_weight *= options.branch_decay;
    }
    EmbeddedDeformationOptions deformation = options.deformation;
    deformation.w_rot *= stiffness;
    deformation.w_reg *= stiffness;
    deformation.w_rig *= stiffness;
    DeformationState next = result.state;
    const SolveSummary solve =
        SolveEmbeddedDeformation(model.graph, constraints, deformation, &next, {}, &scratch);
    if (!solve.usable) break;
    result.state = std::move(next);
    result.rounds = round + 1;
    stiffness = std::max(options.min_stiffness, stiffness * options.stiffness_decay);
  }
  const Eigen::Matrix3Xd posed = DeformPoints(model.graph, weights, rest, result.state);
  // Measured in the target's frame, against its own index, and brought back to template sizes.
  Eigen::Matrix3Xd posed_there(3, ns);
  for (Eigen::Index i = 0; i < ns; ++i) posed_there.col(i) = placement(posed.col(i));
  const PointIndex posed_there_index(posed_there);
  if (options.weigh_by_asymmetry) {
    const std::vector<double> asymmetry = HalfTurnAsymmetry(rest);
    result.disagreement =
        WeightedTrimmedDisagreement(posed_there, posed_there_index, asymmetry, samples_there,
                                    target_index, options.keep_fraction);
  } else {
    result.disagreement = TrimmedDisagreement(posed_there, posed_there_index, samples_there,
                                              target_index, options.keep_fraction);
  }
  result.disagreement /= placement.scale;
  const Eigen::Matrix4d T = Eigen::umeyama(rest, posed, true);
  const Eigen::Matrix3Xd rigid = (T.topLeftCorner<3, 3>() * rest).colwise() + T.topRightCorner<3, 1>();
  result.bend = (posed - rigid).colwise().norm().mean();
  result.ok = true;
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  return result;
}

}  // namespace vb::morph
