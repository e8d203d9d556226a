#include "morph/limb_turn.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "io/error.h"

namespace vb::morph {
namespace {

// Target points of a limb read by the check, at most.
constexpr std::size_t kCheckPoints = 200;
// Relative difference of two swing scores below which they are the same up to rounding.
constexpr double kRounding = 1e-9;

// The least rotation that turns template branch @p a's axis onto target branch @p b's: each
// axis is the principal direction of the branch's samples along the shorter of the two, from
// its root, pointing to its tip. A limb's samples lie near a line, which leaves the turn about
// the line itself undetermined; it stays as it was. @p theirs holds the target's samples in
// the template's frame.
Eigen::Matrix3d LimbTurn(const BranchGuide& guide, const Eigen::Matrix3Xd& theirs, int a, int b,
                         double scale) {
  const double la = guide.limbs->length[static_cast<std::size_t>(a)];
  const double lb = guide.target_length[static_cast<std::size_t>(b)] / scale;
  const double shorter = std::min(la, lb);
  constexpr int n = BranchGuide::kSamples;
  Eigen::Matrix3Xd p(3, n), q(3, n);
  for (int k = 0; k < n; ++k) {
    const double s = shorter * k / (n - 1);
    p.col(k) = guide.limbs->rest.col(BranchGuide::Column(a, BranchGuide::SampleAt(s / la)));
    q.col(k) = theirs.col(BranchGuide::Column(b, BranchGuide::SampleAt(s / lb)));
  }
  const auto axis = [](const Eigen::Matrix3Xd& x) {
    const Eigen::Matrix3Xd centred = x.colwise() - x.rowwise().mean();
    Eigen::Vector3d d =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(centred * centred.transpose())
            .eigenvectors()
            .col(2);
    return d.dot(x.col(x.cols() - 1) - x.col(0)) < 0 ? Eigen::Vector3d(-d) : d;
  };
  return Eigen::Quaterniond::FromTwoVectors(axis(p), axis(q)).toRotationMatrix();
}

// Mean distance from each column of @p from to the nearest of @p to's points.
double MeanNearest(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  const PointIndex index(to);
  double sum = 0.0;
  for (Eigen::Index i = 0; i < from.cols(); ++i)
    sum += (to.col(index.Nearest(from.col(i))) - from.col(i)).norm();
  return sum / static_cast<double>(from.cols());
}

// True when graph node @p j lies on limb @p a at least @p from of the way out.
bool OnLimbFrom(const BranchGuide& guide, std::size_t j, int a, double from) {
  return guide.limbs->node_branch[j] == a && guide.limbs->node_along[j] >= from;
}

// Sets @p out to @p state with every graph node of limb @p a (TemplateLimbs::node_branch) at
// least @p from of the way out (TemplateLimbs::node_along) turned by @p turn and moved so that
// each maps the rest point @p root_rest onto @p root: that part of the limb in its rest shape,
// turned as a whole and hung from @p root. The other nodes keep their transforms.
// @pre @p turn is a rotation.
void CarriedAtRest(const DeformationGraph& graph, const BranchGuide& guide, int a, double from,
                   const Eigen::Matrix3d& turn, const Eigen::Vector3d& root_rest,
                   const Eigen::Vector3d& root, const DeformationState& state,
                   DeformationState* out) {
  *out = state;
  for (int j = 0; j < graph.num_nodes(); ++j) {
    if (!OnLimbFrom(guide, static_cast<std::size_t>(j), a, from)) continue;
    const Eigen::Vector3d g = graph.nodes.col(j);
    // p -> turn (p - root_rest) + root for every point the node carries.
    out->set_rotation(j, turn);
    out->t[static_cast<std::size_t>(j)] = turn * (g - root_rest) + root - g;
  }
}

// A move of a limb's part from a pivot out (SwingLimbs).
struct LimbMove {
  double gain = 0.0;   // how much it lowers the two-way distance (a sum of template sizes)
  double from = -1.0;  // the pivot, a fraction of the branch's length; below 0: no move
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();  // posed
  bool from_rest = false;                           // R turns the part in its rest shape, at_rest
  DeformationState at_rest;
};

// @p count unit vectors spread evenly over the sphere (a Fibonacci lattice).
std::vector<Eigen::Vector3d> SphereDirections(int count) {
  std::vector<Eigen::Vector3d> out;
  const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / count;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    out.emplace_back(r * std::cos(i * golden_angle), r * std::sin(i * golden_angle), z);
  }
  return out;
}

}  // namespace

DeformationState TurnLimbs(const TemplateModel& model, const BranchGuide& guide,
                           const Eigen::Matrix3Xd& target, const PointIndex& target_index,
                           const Similarity& placement, const ArticulationOptions& options,
                           int* turned, const DeformationState* current) {
  VB_DEMAND(target.cols() > 0 && target_index.size() == target.cols());
  VB_DEMAND(placement.Usable());
  VB_DEMAND(guide.limbs != nullptr &&
            static_cast<int>(guide.limbs->node_branch.size()) == model.graph.num_nodes());
  VB_DEMAND(current == nullptr || static_cast<int>(current->t.size()) == model.graph.num_nodes());
  DeformationState state = DeformationState::Identity(model.graph.num_nodes());
  if (turned != nullptr) *turned = 0;
  if (guide.num_template_branches() == 0 || guide.num_target_branches() == 0) return state;
  const Similarity back = placement.Inverse();
  const Eigen::Matrix3Xd theirs = TargetBranchesIn(guide, back);  // template frame

  std::vector<std::vector<int>> limb_nodes(static_cast<std::size_t>(guide.num_template_branches()));
  for (int j = 0; j < model.graph.num_nodes(); ++j) {
    const int a = guide.limbs->node_branch[static_cast<std::size_t>(j)];
    if (a >= 0) limb_nodes[static_cast<std::size_t>(a)].push_back(j);
  }
  for (const auto& [a, b] : PairBranches(guide, guide.limbs->rest, theirs, placement.scale,
                                         options.limb_pair_fraction, options)) {
    const std::vector<int>& nodes = limb_nodes[static_cast<std::size_t>(a)];
    const std::vector<int>& support = guide.target_support[static_cast<std::size_t>(b)];
    if (nodes.size() < 2 || support.empty()) continue;
    const Eigen::Matrix3d R = LimbTurn(guide, theirs, a, b, placement.scale);
    const Eigen::Vector3d root = guide.limbs->rest.col(BranchGuide::Column(a, 0));
    const auto n = static_cast<Eigen::Index>(nodes.size());
    // The limb's nodes at rest, turned, and where the fit so far has them.
    Eigen::Matrix3Xd rest(3, n), moved(3, n), now(3, n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto j = static_cast<std::size_t>(nodes[static_cast<std::size_t>(i)]);
      rest.col(i) = model.graph.nodes.col(static_cast<Eigen::Index>(j));
      moved.col(i) = R * (rest.col(i) - root) + root;
      now.col(i) = current != nullptr ? Eigen::Vector3d(rest.col(i) + current->t[j]) : rest.col(i);
    }
    // A limb the fit so far already brought about where the turn would: turned in the start
    // (not left at rest), but no reason to fit again.
    const bool done =
        current != nullptr && (moved - now).colwise().norm().mean() < options.limb_swing_cap;
    if (!done) {
      // The limb's nodes to the target, in the target's frame.
      double before = 0.0, after = 0.0;
      for (Eigen::Index i = 0; i < n; ++i) {
        const Eigen::Vector3d r = placement(rest.col(i)), m = placement(moved.col(i));
        before += (target.col(target_index.Nearest(r)) - r).norm();
        after += (target.col(target_index.Nearest(m)) - m).norm();
      }
      if (!(after < before)) continue;
      // The target limb's points to the limb's nodes, in the template's frame.
      const std::size_t step = (support.size() + kCheckPoints - 1) / kCheckPoints;
      Eigen::Matrix3Xd seen(3, static_cast<Eigen::Index>((support.size() + step - 1) / step));
      for (std::size_t i = 0, k = 0; i < support.size(); i += step, ++k)
        seen.col(static_cast<Eigen::Index>(k)) = back(target.col(support[i]));
      if (!(MeanNearest(seen, moved) < MeanNearest(seen, rest))) continue;
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      const int j = nodes[static_cast<std::size_t>(i)];
      state.set_rotation(j, R);
      state.t[static_cast<std::size_t>(j)] = moved.col(i) - rest.col(i);
    }
    if (turned != nullptr && !done) ++*turned;
  }
  return state;
}

DeformationState SwingLimbs(const TemplateModel& model, const BranchGuide& guide,
                            const Eigen::Matrix3Xd& target, const PointIndex& target_index,
                            const Similarity& placement, const DeformationState& start,
                            const ArticulationOptions& options, int* swung, WorkerPool* pool,
                            int* beyond_root, RootSwing* about_roots) {
  VB_DEMAND(target.cols() > 0 && target_index.size() == target.cols());
  VB_DEMAND(placement.Usable());
  VB_DEMAND(guide.limbs != nullptr &&
            static_cast<int>(guide.limbs->node_branch.size()) == model.graph.num_nodes());
  VB_DEMAND(guide.limbs->vertex_branch.size() == static_cast<std::size_t>(model.V.cols()));
  VB_DEMAND(guide.limbs->vertex_along.size() == guide.limbs->vertex_branch.size() &&
            guide.limbs->node_along.size() == guide.limbs->node_branch.size());
  VB_DEMAND(static_cast<int>(start.t.size()) == model.graph.num_nodes());
  DeformationState state = start;
  if (swung != nullptr) *swung = 0;
  if (beyond_root != nullptr) *beyond_root = 0;
  if (about_roots != nullptr) *about_roots = RootSwing{start, 0};
  const int num_limbs = guide.num_template_branches();
  if (num_limbs == 0 || options.limb_swing_directions <= 0) return state;
  const Similarity back = placement.Inverse();
  const double cap = options.limb_swing_cap;

  // The template's samples with their node weights, and the target's in the template's frame.
  const TemplateSamples sampled = SampleTemplate(model, options.template_samples);
  const std::vector<int>& ids = sampled.ids;
  const auto ns = static_cast<Eigen::Index>(ids.size());
  const std::vector<int> target_ids = Spread(target.cols(), options.target_samples);
  Eigen::Matrix3Xd seen(3, static_cast<Eigen::Index>(target_ids.size()));
  for (std::size_t k = 0; k < target_ids.size(); ++k)
    seen.col(static_cast<Eigen::Index>(k)) = back(target.col(target_ids[k]));
  const std::vector<Eigen::Vector3d> directions = SphereDirections(options.limb_swing_directions);

  std::vector<int> order(static_cast<std::size_t>(num_limbs));
  for (int a = 0; a < num_limbs; ++a) order[static_cast<std::size_t>(a)] = a;
  std::stable_sort(order.begin(), order.end(), [&](int x, int y) {
    return guide.limbs->length[static_cast<std::size_t>(x)] >
           guide.limbs->length[static_cast<std::size_t>(y)];
  });
  std::vector<bool> has_nodes(static_cast<std::size_t>(num_limbs), false);
  for (const int a : guide.limbs->node_branch)
    if (a >= 0) has_nodes[static_cast<std::size_t>(a)] = true;
  std::vector<double> scores(directions.size());
  // Each direction's swung limb, grown to the largest limb scored: the scores below write
  // into them instead of allocating a limb each.
  std::vector<Eigen::Matrix3Xd> swing_buffers(directions.size());
  // One move's sample lists, reused from move to move (cleared, not reallocated).
  std::vector<Eigen::Index> mine, others, near;
  std::vector<double> elsewhere;
  // One move's limb samples (posed, and in the rest shape) and a shape less its root, in the
  // leading columns of buffers grown to the largest limb.
  Eigen::Matrix3Xd limb_buffer, rest_limb_buffer, centred_buffer;
  // A move's state with the limb in its rest shape, and the translations before a move.
  DeformationState at_rest;
  std::vector<Eigen::Vector3d> before;
  const auto leading = [](Eigen::Matrix3Xd* buffer, std::size_t n) {
    const auto cols = static_cast<Eigen::Index>(n);
    if (buffer->cols() < cols) buffer->resize(3, cols);
    return buffer->leftCols(cols);
  };
  const int pivots = std::max(1, options.limb_swing_pivots);
  // The best move of limb @p a's part from @p fraction of its branch out (rounded to the
  // branch's samples), from @p from_state (@p posed: the samples as it poses them); none
  // (from < 0) when no move beats its place.
  const auto move_from = [&](const DeformationState& from_state, const Eigen::Matrix3Xd& posed,
                             int a, double fraction) {
    const LimbMove none;
    const int column = BranchGuide::SampleAt(fraction);
    const double from = column / (BranchGuide::kSamples - 1.0);
    mine.clear();
    others.clear();
    for (Eigen::Index k = 0; k < ns; ++k) {
      const auto v = static_cast<std::size_t>(ids[static_cast<std::size_t>(k)]);
      (guide.limbs->vertex_branch[v] == a && guide.limbs->vertex_along[v] >= from ? mine : others)
          .push_back(k);
    }
    if (mine.size() < 3 || others.empty()) return none;
    bool carried = false;  // by a graph node the move turns
    for (std::size_t j = 0; j < guide.limbs->node_branch.size() && !carried; ++j)
      carried = OnLimbFrom(guide, j, a, from);
    if (!carried) return none;
    auto limb = leading(&limb_buffer, mine.size());
    for (std::size_t k = 0; k < mine.size(); ++k)
      limb.col(static_cast<Eigen::Index>(k)) = posed.col(mine[k]);
    const Eigen::Matrix3Xd trunk = posed(Eigen::all, others);
    const Eigen::Index root_column = BranchGuide::Column(a, column);
    const Eigen::Vector3d root = DeformPoint(model.graph, guide.limbs->weights, root_column,
                                             guide.limbs->rest.col(root_column), from_state);
    const Eigen::Vector3d axis = limb.rowwise().mean() - root;
    if (!(axis.norm() > 0)) return none;
    const double reach = (limb.colwise() - root).colwise().norm().maxCoeff();
    // The target's samples the limb can change: nearer its reach than to the rest of the
    // template and the cap. The others count the same in every direction.
    const PointIndex trunk_index(trunk);
    near.clear();
    elsewhere.clear();
    for (Eigen::Index y = 0; y < seen.cols(); ++y) {
      const double d =
          std::min(cap, (trunk.col(trunk_index.Nearest(seen.col(y))) - seen.col(y)).norm());
      if ((seen.col(y) - root).norm() - reach < d) {
        near.push_back(y);
        elsewhere.push_back(d);
      }
    }
    // Two-way capped distance of @p shape (@p centred: less the root), swung by R about the
    // root into @p buffer.
    const auto score = [&](const Eigen::Ref<const Eigen::Matrix3Xd>& centred,
                           const Eigen::Matrix3d& R, Eigen::Matrix3Xd* buffer) {
      if (buffer->cols() < centred.cols()) buffer->resize(3, centred.cols());
      auto swung_limb = buffer->leftCols(centred.cols());
      swung_limb.noalias() = R * centred;
      swung_limb.colwise() += root;
      double sum = 0.0;
      for (Eigen::Index i = 0; i < swung_limb.cols(); ++i) {
        const Eigen::Vector3d there = placement(swung_limb.col(i));
        sum += std::min(cap,
                        (target.col(target_index.Nearest(there)) - there).norm() / placement.scale);
      }
      for (std::size_t k = 0; k < near.size(); ++k) {
        const double d =
            (swung_limb.colwise() - seen.col(near[k])).colwise().squaredNorm().minCoeff();
        sum += std::min(elsewhere[k], std::sqrt(d));
      }
      return sum;
    };
    // The best swing of @p shape (its axis laid on each direction), and its score.
    const auto best_swing = [&](const Eigen::Ref<const Eigen::Matrix3Xd>& shape) {
      const Eigen::Vector3d shape_axis = shape.rowwise().mean() - root;
      const auto turn_to = [&](std::size_t k) {
        return Eigen::Matrix3d(
            Eigen::Quaterniond::FromTwoVectors(shape_axis, directions[k]).toRotationMatrix());
      };
      auto centred = leading(&centred_buffer, static_cast<std::size_t>(shape.cols()));
      centred = shape.colwise() - root;
      ForEach(pool, static_cast<int>(directions.size()), [&](int k) {
        const auto d = static_cast<std::size_t>(k);
        scores[d] = score(centred, turn_to(d), &swing_buffers[d]);
      });
      const auto k =
          static_cast<std::size_t>(std::min_element(scores.begin(), scores.end()) - scores.begin());
      return std::pair<Eigen::Matrix3d, double>(turn_to(k), scores[k]);
    };
    auto [R, best] = best_swing(limb);
    // The fit may have bent the limb out of shape (folded along a neighbour it lay on): the
    // limb is also tried in its rest shape, turned as the graph node that weighs most at its
    // root is (the nearest rotation of that node's transform) and hung from the posed root.
    Eigen::Index slot = 0;
    guide.limbs->weights.weights.col(root_column).maxCoeff(&slot);
    // -1 only for a root no node reaches
    const int carrier = guide.limbs->weights.nodes(slot, root_column);
    bool from_rest = false;
    if (carrier >= 0) {
      CarriedAtRest(model.graph, guide, a, from,
                    NearestRotation(Eigen::JacobiSVD<Eigen::Matrix3d>(
                        from_state.rotation(carrier), Eigen::ComputeFullU | Eigen::ComputeFullV)),
                    guide.limbs->rest.col(root_column), root, from_state, &at_rest);
      // The limb's samples alone, as DeformPoints would move them.
      auto rest_limb = leading(&rest_limb_buffer, mine.size());
      for (std::size_t k = 0; k < mine.size(); ++k)
        rest_limb.col(static_cast<Eigen::Index>(k)) =
            DeformPoint(model.graph, sampled.weights, mine[k], sampled.rest.col(mine[k]), at_rest);
      if ((rest_limb.rowwise().mean() - root).norm() > 0) {
        auto [rest_R, rest_best] = best_swing(rest_limb);
        // Unfolded where it is, not swung: the lattice of directions may hold none as near.
        auto centred = leading(&centred_buffer, mine.size());
        centred = rest_limb.colwise() - root;
        const double unswung = score(centred, Eigen::Matrix3d::Identity(), &swing_buffers.front());
        if (unswung <= rest_best) {
          rest_R = Eigen::Matrix3d::Identity();
          rest_best = unswung;
        }
        if (rest_best < best) {
          R = rest_R;
          best = rest_best;
          from_rest = true;
        }
      }
    }
    // Beaten by more than rounding: the rest shape of a limb the fit left unbent scores its
    // own place up to the last digits, and is no swing. The cap, the most one distance adds,
    // keeps that margin for a limb that already lies on the target (a score near 0).
    auto centred = leading(&centred_buffer, mine.size());
    centred = limb.colwise() - root;
    const double own = score(centred, Eigen::Matrix3d::Identity(), &swing_buffers.front());
    if (!(best < own - kRounding * (own + cap))) return none;
    LimbMove m;
    m.gain = own - best;
    m.from = from;
    m.R = R;
    m.pivot = root;
    m.from_rest = from_rest;
    if (from_rest) m.at_rest = at_rest;
    return m;
  };
  // @p m done to @p into: every graph node of limb @p a from the pivot out turns about it,
  // p -> R (T_j(p) - pivot) + pivot, after that part is put in its rest shape when from_rest.
  // Returns how far the moved nodes went, mean, template sizes.
  const auto apply = [&](const LimbMove& m, int a, DeformationState* into) {
    before = into->t;
    if (m.from_rest) *into = m.at_rest;
    double travel = 0.0;
    int count = 0;
    for (int j = 0; j < model.graph.num_nodes(); ++j) {
      const auto jj = static_cast<std::size_t>(j);
      if (!OnLimbFrom(guide, jj, a, m.from)) continue;
      const Eigen::Vector3d g = model.graph.nodes.col(j);
      into->set_rotation(j, m.R * into->rotation(j));
      into->t[jj] = m.R * (g + into->t[jj] - m.pivot) + m.pivot - g;
      travel += (into->t[jj] - before[jj]).norm();
      ++count;
    }
    return count > 0 ? travel / count : 0.0;
  };
  // Two tracks when both are asked for: about the pivots (state) and about the roots alone.
  // They share each limb's move about its root while no limb has moved about a pivot beyond.
  const bool both = about_roots != nullptr && pivots > 1;
  DeformationState roots_state;
  if (both) roots_state = start;
  bool apart = false;
  int moved = 0;
  for (const int a : order) {
    if (!has_nodes[static_cast<std::size_t>(a)]) continue;  // nothing it could move
    const Eigen::Matrix3Xd posed = DeformPoints(model.graph, sampled.weights, sampled.rest, state);
    // The best move over the pivots, the one lowering the two-way distance most. Each
    // pivot's gain is nearly the same sum's change (target samples the moved part cannot
    // reach count alike either way; only samples inside the pivot that nodes beyond it also
    // carry move unscored).
    LimbMove best = move_from(state, posed, a, 0.0);
    if (both) {
      const LimbMove at_root =
          apart ? move_from(roots_state,
                            DeformPoints(model.graph, sampled.weights, sampled.rest, roots_state),
                            a, 0.0)
                : best;
      if (at_root.from >= 0) {
        apply(at_root, a, &roots_state);
        ++about_roots->swung;
      }
    }
    for (int p = 1; p < pivots; ++p) {
      LimbMove m = move_from(state, posed, a, static_cast<double>(p) / (pivots + 1));
      if (m.from >= 0 && m.gain > best.gain) best = std::move(m);
    }
    if (best.from < 0) continue;
    const double travel = apply(best, a, &state);
    ++moved;
    if (best.from > 0) {
      apart = true;
      // A part moved less than the cap is a nudge the fit itself can make, not a reason to fit
      // again from the swing about the pivots.
      if (beyond_root != nullptr && travel >= cap) ++*beyond_root;
    }
  }
  if (swung != nullptr) *swung = moved;
  if (both) {
    about_roots->state = std::move(roots_state);
  } else if (about_roots != nullptr) {
    *about_roots = RootSwing{state, moved};  // about the roots alone already
  }
  return state;
}

DeformationState ReclaimLimbs(const TemplateModel& model, const BranchGuide& guide,
                              const Eigen::Matrix3Xd& target, const Similarity& placement,
                              const DeformationState& start, const ArticulationOptions& options,
                              int* reclaimed) {
  VB_DEMAND(placement.Usable() && reclaimed != nullptr);
  VB_DEMAND(guide.limbs != nullptr &&
            static_cast<int>(guide.limbs->node_branch.size()) == model.graph.num_nodes());
  VB_DEMAND(static_cast<int>(start.t.size()) == model.graph.num_nodes());
  VB_DEMAND(static_cast<int>(guide.target_support.size()) == guide.num_target_branches() &&
            guide.target_points.cols() ==
                static_cast<Eigen::Index>(guide.num_target_branches()) * BranchGuide::kSamples);
  *reclaimed = 0;
  DeformationState state = start;
  const int num_limbs = guide.num_template_branches(), num_theirs = guide.num_target_branches();
  if (num_limbs == 0 || num_theirs == 0 || !(options.reclaim_uncovered > 0)) return state;
  constexpr int n = BranchGuide::kSamples;
  const Similarity back = placement.Inverse();
  // The target's limbs, in the template's frame, by how far the posed template leaves their
  // points.
  const Eigen::Matrix3Xd posed = DeformPoints(model.graph, model.vertex_weights, model.V, start);
  const PointIndex posed_index(posed);
  std::vector<std::pair<double, int>> uncovered;  // (-distance, target branch)
  // A limb the fit laid along the trunk covers its target limb's root and leaves its end
  // bare: the points nearest the branch's outer half are read, all of them where none are
  // (nearest in the target's frame, as the similarity leaves it).
  for (int b = 0; b < num_theirs; ++b) {
    const std::vector<int>& support = guide.target_support[static_cast<std::size_t>(b)];
    if (support.empty()) continue;
    double sum = 0.0, outer_sum = 0.0;
    int count = 0, outer_count = 0;
    for (std::size_t i = 0; i < support.size(); i += 1 + support.size() / kCheckPoints, ++count) {
      const Eigen::Vector3d p = back(target.col(support[i]));
      const double d = (posed.col(posed_index.Nearest(p)) - p).norm();
      sum += d;
      Eigen::Index k = 0;
      (guide.target_points.middleCols(static_cast<Eigen::Index>(b) * n, n).colwise() -
       target.col(support[i]))
          .colwise()
          .squaredNorm()
          .minCoeff(&k);
      if (k >= n / 2) {
        outer_sum += d;
        ++outer_count;
      }
    }
    const double reading = outer_count > 0 ? outer_sum / outer_count : sum / count;
    if (reading > options.reclaim_uncovered) uncovered.emplace_back(-reading, b);
  }
  if (uncovered.empty()) return state;
  std::sort(uncovered.begin(), uncovered.end());
  const Eigen::Matrix3Xd theirs = TargetBranchesIn(guide, back);
  const auto branch = [&](int b) { return theirs.middleCols(static_cast<Eigen::Index>(b) * n, n); };
  // Each template limb's samples as posed, and how far its outer half lies from every target
  // limb: the farther, the readier it is to move.
  const Eigen::Matrix3Xd limbs =
      DeformPoints(model.graph, guide.limbs->weights, guide.limbs->rest, start);
  std::vector<double> astray(static_cast<std::size_t>(num_limbs));
  for (int a = 0; a < num_limbs; ++a) {
    double least = std::numeric_limits<double>::infinity();
    for (int b = 0; b < num_theirs; ++b) {
      double sum = 0.0;
      for (int k = n / 2; k < n; ++k)
        sum += (branch(b).colwise() - limbs.col(BranchGuide::Column(a, k)))
                   .colwise()
                   .norm()
                   .minCoeff();
      least = std::min(least, sum / (n - n / 2));
    }
    astray[static_cast<std::size_t>(a)] = least;
  }
  std::vector<bool> movable(static_cast<std::size_t>(num_limbs), false);
  for (const int a : guide.limbs->node_branch)
    if (a >= 0) movable[static_cast<std::size_t>(a)] = true;
  for (const auto& [ignored, b] : uncovered) {
    int pick = -1;
    double best = std::numeric_limits<double>::infinity();
    for (int a = 0; a < num_limbs; ++a) {
      if (!movable[static_cast<std::size_t>(a)]) continue;
      const Eigen::Vector3d root = limbs.col(BranchGuide::Column(a, 0));
      const double reach = (branch(b).colwise() - root).colwise().norm().minCoeff();
      if (!(reach <= options.reclaim_root)) continue;
      const double cost = reach - astray[static_cast<std::size_t>(a)];
      if (cost < best) {
        best = cost;
        pick = a;
      }
    }
    if (pick < 0) continue;
    const auto rest = guide.limbs->rest.middleCols(static_cast<Eigen::Index>(pick) * n, n);
    const Eigen::Vector3d root_rest = rest.col(0);
    const Eigen::Vector3d root = limbs.col(BranchGuide::Column(pick, 0));
    const Eigen::Vector3d axis = rest.rowwise().mean() - root_rest;
    const Eigen::Vector3d wanted = branch(b).rowwise().mean() - root;
    if (!(axis.norm() > 0 && wanted.norm() > 0)) continue;
    DeformationState turned;
    CarriedAtRest(model.graph, guide, pick, 0.0,
                  Eigen::Quaterniond::FromTwoVectors(axis, wanted).toRotationMatrix(), root_rest,
                  root, state, &turned);
    state = std::move(turned);
    movable[static_cast<std::size_t>(pick)] = false;
    ++*reclaimed;
  }
  return state;
}

}  // namespace vb::morph
