#include "morph/articulated_fit.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "io/error.h"

namespace vb::morph {
namespace {

// The value below which the nearest @p keep_fraction of @p d lie.
double KeepLimit(std::vector<double> d, double keep_fraction) {
  if (d.empty()) return 0.0;
  const auto cut = static_cast<std::size_t>(keep_fraction * static_cast<double>(d.size() - 1));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(cut), d.end());
  return d[cut];
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

// Evenly spread column indices of a matrix with @p n columns, about @p wanted of them.
std::vector<int> Spread(Eigen::Index n, int wanted) {
  std::vector<int> out;
  const Eigen::Index step = std::max<Eigen::Index>(1, n / std::max(1, wanted));
  for (Eigen::Index i = 0; i < n; i += step) out.push_back(static_cast<int>(i));
  return out;
}

}  // namespace

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

double TrimmedDisagreement(const Eigen::Matrix3Xd& a, const PointIndex& a_index,
                           const Eigen::Matrix3Xd& b_samples, const PointIndex& b_index,
                           double keep_fraction) {
  VB_DEMAND(a_index.size() > 0 && b_index.size() > 0);
  std::vector<double> forward(static_cast<std::size_t>(a.cols()));
  std::vector<double> backward(static_cast<std::size_t>(b_samples.cols()));
  std::vector<int> k;
  std::vector<double> d2;
  for (Eigen::Index i = 0; i < a.cols(); ++i) {
    b_index.Nearest(a.col(i), 1, &k, &d2);
    forward[static_cast<std::size_t>(i)] = std::sqrt(d2.front());
  }
  for (Eigen::Index i = 0; i < b_samples.cols(); ++i) {
    a_index.Nearest(b_samples.col(i), 1, &k, &d2);
    backward[static_cast<std::size_t>(i)] = std::sqrt(d2.front());
  }
  return 0.5 * (TrimmedMean(std::move(forward), keep_fraction) +
                TrimmedMean(std::move(backward), keep_fraction));
}

ArticulationResult ArticulateTemplate(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                                      const PointIndex& target_index,
                                      const Eigen::Matrix3Xd& target_terminals,
                                      const DeformationState& start,
                                      const ArticulationOptions& options,
                                      const Similarity& placement) {
  const auto begin = std::chrono::steady_clock::now();
  VB_DEMAND(target.cols() > 0 && target_index.size() == target.cols());
  VB_DEMAND(placement.Usable());
  const Similarity back = placement.Inverse();  // target frame -> template frame
  ArticulationResult result;
  result.state = start;

  // The template samples with their node weights, and the target samples.
  const std::vector<int> template_ids = Spread(model.V.cols(), options.template_samples);
  const auto ns = static_cast<Eigen::Index>(template_ids.size());
  Eigen::Matrix3Xd rest(3, ns);
  NodeWeights weights;
  weights.nodes.resize(model.vertex_weights.nodes.rows(), ns);
  weights.weights.resize(model.vertex_weights.weights.rows(), ns);
  for (Eigen::Index k = 0; k < ns; ++k) {
    const int v = template_ids[static_cast<std::size_t>(k)];
    rest.col(k) = model.V.col(v);
    weights.nodes.col(k) = model.vertex_weights.nodes.col(v);
    weights.weights.col(k) = model.vertex_weights.weights.col(v);
  }
  // The target samples in the target's frame (for the final disagreement) and in the
  // template's (for the fit).
  const std::vector<int> target_ids = Spread(target.cols(), options.target_samples);
  const Eigen::Matrix3Xd samples_there = target(Eigen::all, target_ids);
  Eigen::Matrix3Xd target_samples(3, samples_there.cols());
  for (Eigen::Index k = 0; k < samples_there.cols(); ++k)
    target_samples.col(k) = back(samples_there.col(k));

  Eigen::Matrix3Xd terminals(3, target_terminals.cols());  // template frame
  for (Eigen::Index t = 0; t < terminals.cols(); ++t)
    terminals.col(t) = back(target_terminals.col(t));

  std::vector<PointConstraint> constraints;
  std::vector<double> forward(static_cast<std::size_t>(ns));
  Eigen::Matrix3Xd forward_partner(3, ns);  // template frame
  std::vector<double> backward(target_ids.size());
  std::vector<int> backward_partner(target_ids.size());
  double stiffness = options.stiffness_start;
  for (int round = 0; round < options.rounds; ++round) {
    const Eigen::Matrix3Xd posed = DeformPoints(model.graph, weights, rest, result.state);
    const PointIndex posed_index(posed);
    for (Eigen::Index i = 0; i < ns; ++i) {
      forward_partner.col(i) = back(target.col(target_index.Nearest(placement(posed.col(i)))));
      forward[static_cast<std::size_t>(i)] = (forward_partner.col(i) - posed.col(i)).norm();
    }
    for (Eigen::Index k = 0; k < target_samples.cols(); ++k) {
      const int i = posed_index.Nearest(target_samples.col(k));
      backward_partner[static_cast<std::size_t>(k)] = i;
      backward[static_cast<std::size_t>(k)] = (target_samples.col(k) - posed.col(i)).norm();
    }
    const double forward_limit = KeepLimit(forward, options.keep_fraction);
    const double backward_limit = KeepLimit(backward, options.target_keep_fraction);
    constraints.clear();
    for (Eigen::Index i = 0; i < ns; ++i) {
      if (forward[static_cast<std::size_t>(i)] > forward_limit) continue;
      constraints.push_back(ConstrainPoint(weights, i, rest.col(i), forward_partner.col(i)));
    }
    for (Eigen::Index k = 0; k < target_samples.cols(); ++k) {
      if (backward[static_cast<std::size_t>(k)] > backward_limit) continue;
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
    EmbeddedDeformationOptions deformation = options.deformation;
    deformation.w_rot *= stiffness;
    deformation.w_reg *= stiffness;
    deformation.w_rig *= stiffness;
    DeformationState next = result.state;
    const SolveSummary solve =
        SolveEmbeddedDeformation(model.graph, constraints, deformation, &next);
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
  result.disagreement = TrimmedDisagreement(posed_there, posed_there_index, samples_there,
                                            target_index, options.keep_fraction) /
                        placement.scale;
  const Eigen::Matrix4d T = Eigen::umeyama(rest, posed, true);
  const Eigen::Matrix3Xd rigid = (T.topLeftCorner<3, 3>() * rest).colwise() + T.topRightCorner<3, 1>();
  result.bend = (posed - rigid).colwise().norm().mean();
  result.ok = true;
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  return result;
}

}  // namespace vb::morph
