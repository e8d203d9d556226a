#include "morph/feature_association.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace vb::morph {

Eigen::Matrix3d NearestRotation(const Eigen::JacobiSVD<Eigen::Matrix3d>& svd) {
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

Similarity Similarity::FromUmeyama(const Eigen::Matrix4d& T) {
  Similarity fit;
  const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
  fit.scale = std::cbrt(sR.determinant());
  fit.R = sR / fit.scale;
  fit.t = T.topRightCorner<3, 1>();
  return fit;
}

namespace {

struct Search {
  // Candidate points: terminals first, then junctions.
  Eigen::Matrix3Xd a, b;
  int a_terminals = 0, b_terminals = 0;
  bool prune = true;
  int max_terminal_skips = 1, max_junction_skips = 1;
  int terminal_skips = 0, junction_skips = 0;
  std::vector<int> a_slots;  // which `a` nodes get paired (the smaller side of each kind)
  bool a_is_from = true;
  const AssociationOptions* options = nullptr;

  std::vector<int> assignment;  // per slot, index into b
  std::vector<bool> used;
  struct Candidate {
    double cost;
    std::vector<int> slots, assignment;
    Similarity fit;
  };
  std::vector<Candidate> best;  // sorted by cost, at most keep
  // Evaluate's paired points on a and on b, one pair of matrices per count of pairs.
  std::vector<std::pair<Eigen::Matrix3Xd, Eigen::Matrix3Xd>> paired;
  std::size_t keep = 16;
  long candidates = 0, pruned = 0;

  bool Consistent(std::size_t depth) const {
    // Ratios of paired distances must agree within the allowed stretch.
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    // Terminal-to-terminal distances only: junction placement depends on the skeletoniser.
    for (std::size_t i = 0; i <= depth; ++i) {
      if (a_slots[i] >= a_terminals || assignment[i] < 0) continue;
      for (std::size_t j = i + 1; j <= depth; ++j) {
        if (a_slots[j] >= a_terminals || assignment[j] < 0) continue;
        const double da = (a.col(a_slots[i]) - a.col(a_slots[j])).norm();
        const double db = (b.col(assignment[i]) - b.col(assignment[j])).norm();
        if (da < 1e-12 || db < 1e-12) continue;
        lo = std::min(lo, db / da);
        hi = std::max(hi, db / da);
      }
    }
    return hi <= options->max_relative_stretch * lo || hi == 0.0;
  }

  // The pairs' points, a's side and b's, into @p on_a and @p on_b (3 by n); the similarity
  // from the `from` side onto the other into @p fit; returns its squared residual.
  template <class Points>
  double FitPairs(Eigen::Index n, Points* on_a, Points* on_b, Similarity* fit) const {
    on_a->resize(3, n);
    on_b->resize(3, n);
    for (std::size_t i = 0, k = 0; i < a_slots.size(); ++i) {
      if (assignment[i] < 0) continue;
      on_a->col(static_cast<Eigen::Index>(k)) = a.col(a_slots[i]);
      on_b->col(static_cast<Eigen::Index>(k)) = b.col(assignment[i]);
      ++k;
    }
    const Points& src = a_is_from ? *on_a : *on_b;
    const Points& dst = a_is_from ? *on_b : *on_a;
    const Eigen::Matrix4d T = Eigen::umeyama(src, dst, true);
    const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
    *fit = Similarity::FromUmeyama(T);
    return ((sR * src).colwise() + T.topRightCorner<3, 1>() - dst).squaredNorm();
  }

  void Evaluate() {
    Eigen::Index n = 0;
    for (int j : assignment) n += j >= 0 ? 1 : 0;
    if (n < 3) return;
    // Up to kInlinePairs pairs, the points and every temporary of the fit live on the stack:
    // this runs thousands of times a search.
    constexpr int kInlinePairs = 32;
    using InlinePoints = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, kInlinePairs>;
    Similarity fit;
    double cost = 0.0;
    if (n <= kInlinePairs) {
      InlinePoints on_a, on_b;
      cost = FitPairs(n, &on_a, &on_b, &fit);
    } else {
      const auto count = static_cast<std::size_t>(n);
      if (paired.size() <= count) paired.resize(count + 1);
      auto& [on_a, on_b] = paired[count];  // allocates only the first time for this count
      cost = FitPairs(n, &on_a, &on_b, &fit);
    }
    ++candidates;
    if (!options->AcceptsOrientation(fit.R)) return;
    // Rank by residual per degree of freedom left after the 7-parameter similarity (fewer
    // pairs always fit better), doubled for every feature left unpaired: leaving one out
    // must at least halve the residual, as a spur or a merged limb does; the floor keeps
    // exact fits preferring more pairs.
    const double per_dof = cost / static_cast<double>(std::max<Eigen::Index>(1, 3 * n - 7)) + 1e-12;
    cost = per_dof * std::pow(2.0, terminal_skips + junction_skips);
    if (best.size() == keep && cost >= best.back().cost) return;
    const auto at = static_cast<std::ptrdiff_t>(
        std::upper_bound(best.begin(), best.end(), cost,
                         [](double c, const Candidate& y) { return c < y.cost; }) -
        best.begin());
    if (best.size() == keep && static_cast<std::size_t>(at) == keep) return;  // a NaN cost
    // A full list's last candidate drops out: its lists take the new one's, which then moves
    // to its place (no allocation once the list is full).
    if (best.size() < keep) best.emplace_back();
    Candidate& slot = best.back();
    slot.cost = cost;
    slot.slots.assign(a_slots.begin(), a_slots.end());
    slot.assignment.assign(assignment.begin(), assignment.end());
    slot.fit = fit;
    std::rotate(best.begin() + at, best.end() - 1, best.end());
  }

  void Recurse(std::size_t depth) {
    if (depth == a_slots.size()) {
      Evaluate();
      return;
    }
    const bool terminal = a_slots[depth] < a_terminals;
    const int begin = terminal ? 0 : b_terminals;
    const int end = terminal ? b_terminals : static_cast<int>(b.cols());
    // Leave this feature unpaired (a spur, or a limb the other skeleton merged away).
    int& skips = terminal ? terminal_skips : junction_skips;
    if (skips < (terminal ? max_terminal_skips : max_junction_skips)) {
      ++skips;
      assignment[depth] = -1;
      Recurse(depth + 1);
      --skips;
    }
    for (int j = begin; j < end; ++j) {
      if (used[static_cast<std::size_t>(j)]) continue;
      assignment[depth] = j;
      if (prune && depth >= 2 && !Consistent(depth)) {
        ++pruned;
        continue;
      }
      used[static_cast<std::size_t>(j)] = true;
      Recurse(depth + 1);
      used[static_cast<std::size_t>(j)] = false;
    }
  }
};

// The feature nodes' positions, which are all the search reads of them.
struct NodePositions {
  Eigen::Matrix3Xd terminals, junctions;
  int num_terminals() const { return static_cast<int>(terminals.cols()); }
  int num_junctions() const { return static_cast<int>(junctions.cols()); }
};

Eigen::Matrix3Xd Stack(const NodePositions& f) {
  Eigen::Matrix3Xd all(3, f.num_terminals() + f.num_junctions());
  all << f.terminals, f.junctions;
  return all;
}

double Permutations(int n, int k) {
  double p = 1.0;
  for (int i = 0; i < k; ++i) p *= n - i;
  return p;
}

// Keeps @p keep columns of @p points, ordered by distance to @p centre, farthest first when
// @p farthest: limb ends are the most telling terminals, central nodes the most reliable
// junctions.
void KeepByDistance(const Eigen::Vector3d& centre, int keep, bool farthest,
                    Eigen::Matrix3Xd* points) {
  if (points->cols() <= keep) return;
  std::vector<int> order(static_cast<std::size_t>(points->cols()));
  for (int i = 0; i < points->cols(); ++i) order[static_cast<std::size_t>(i)] = i;
  std::sort(order.begin(), order.end(), [&](int x, int y) {
    const double dx = (points->col(x) - centre).squaredNorm(),
                 dy = (points->col(y) - centre).squaredNorm();
    return farthest ? dx > dy : dx < dy;
  });
  Eigen::Matrix3Xd kept(3, keep);
  for (int i = 0; i < keep; ++i) kept.col(i) = points->col(order[static_cast<std::size_t>(i)]);
  *points = std::move(kept);
}

}  // namespace

std::vector<Association> AssociateFeatureNodes(const FeatureNodes& from_in,
                                               const FeatureNodes& to_in,
                                               const AssociationOptions& options) {
  NodePositions from{from_in.terminals, from_in.junctions}, to{to_in.terminals, to_in.junctions};
  auto count = [&]() {
    // Pairings, times the ways of leaving one terminal and one junction out.
    const int t = std::min(from.num_terminals(), to.num_terminals());
    const int j = std::min(from.num_junctions(), to.num_junctions());
    return Permutations(std::max(from.num_terminals(), to.num_terminals()), t) * (t + 1) *
           Permutations(std::max(from.num_junctions(), to.num_junctions()), j) * (j + 1);
  };
  // Trim the larger side first: terminals down to four, then junctions down to one.
  while (count() > static_cast<double>(options.max_candidates)) {
    NodePositions& larger_t = from.num_terminals() >= to.num_terminals() ? from : to;
    NodePositions& larger_j = from.num_junctions() >= to.num_junctions() ? from : to;
    if (larger_t.num_terminals() > 4) {
      KeepByDistance(Stack(larger_t).rowwise().mean(), larger_t.num_terminals() - 1, true,
                     &larger_t.terminals);
    } else if (larger_j.num_junctions() > 1) {
      KeepByDistance(Stack(larger_j).rowwise().mean(), larger_j.num_junctions() - 1, false,
                     &larger_j.junctions);
    } else {
      break;  // at most 4! * 5 * 2 pairings: small
    }
  }

  std::vector<Association> results;
  const int pairs = std::min(from.num_terminals(), to.num_terminals()) +
                    std::min(from.num_junctions(), to.num_junctions());
  if (pairs < 3) return results;

  // Search from the side with fewer nodes of each kind; to keep one search tree, `a` is the
  // side with fewer terminals and every junction of `a` is paired when it has fewer too.
  Search s;
  s.a_is_from = from.num_terminals() <= to.num_terminals();
  const NodePositions& fa = s.a_is_from ? from : to;
  const NodePositions& fb = s.a_is_from ? to : from;
  s.a = Stack(fa);
  s.b = Stack(fb);
  s.a_terminals = fa.num_terminals();
  s.b_terminals = fb.num_terminals();
  s.keep = static_cast<std::size_t>(std::max(1, options.keep_best));
  s.best.reserve(s.keep);
  s.options = &options;
  for (int i = 0; i < fa.num_terminals(); ++i) s.a_slots.push_back(i);
  // Junctions: pair all of a's if it has no more than b; otherwise only as many as b has,
  // trying every subset of a's junctions.
  const int ja = fa.num_junctions(), jb = fb.num_junctions();
  std::vector<std::vector<int>> junction_subsets;
  if (ja <= jb) {
    junction_subsets.emplace_back();
    for (int j = 0; j < ja; ++j) junction_subsets.back().push_back(fa.num_terminals() + j);
  } else {
    std::vector<bool> pick(static_cast<std::size_t>(ja), false);
    std::fill(pick.begin(), pick.begin() + jb, true);
    do {
      junction_subsets.emplace_back();
      for (int j = 0; j < ja; ++j) {
        if (pick[static_cast<std::size_t>(j)])
          junction_subsets.back().push_back(fa.num_terminals() + j);
      }
    } while (std::prev_permutation(pick.begin(), pick.end()));
  }
  // If distance-ratio pruning leaves nothing (spurious or missing terminals), search again
  // without it.
  for (bool prune : {true, false}) {
    s.prune = prune;
    for (const auto& subset : junction_subsets) {
      s.a_slots.resize(static_cast<std::size_t>(fa.num_terminals()));
      s.a_slots.insert(s.a_slots.end(), subset.begin(), subset.end());
      s.assignment.assign(s.a_slots.size(), -1);
      s.used.assign(static_cast<std::size_t>(s.b.cols()), false);
      s.Recurse(0);
    }
    if (!s.best.empty()) break;
  }
  // Map back to the caller's (untrimmed) indices by position.
  auto original_index = [](const Eigen::Matrix3Xd& trimmed, const Eigen::Matrix3Xd& original,
                           int i) {
    for (int k = 0; k < original.cols(); ++k) {
      if (original.col(k) == trimmed.col(i)) return k;
    }
    return i;
  };
  results.reserve(s.best.size());
  for (const Search::Candidate& c : s.best) {
    Association result;
    result.ok = true;
    result.candidates = s.candidates;
    result.pruned = s.pruned;
    result.from_to = c.fit;
    result.rms_residual = std::sqrt(c.cost);  // per degree of freedom
    result.terminals.reserve(static_cast<std::size_t>(fa.num_terminals()));
    result.junctions.reserve(c.slots.size() - static_cast<std::size_t>(fa.num_terminals()));
    for (std::size_t k = 0; k < c.slots.size(); ++k) {
      const int ia = c.slots[k], ib = c.assignment[k];
      if (ib < 0) continue;
      const bool terminal = ia < fa.num_terminals();
      int from_index = s.a_is_from ? ia : ib;
      int to_index = s.a_is_from ? ib : ia;
      if (terminal) {
        from_index = original_index(from.terminals, from_in.terminals, from_index);
        to_index = original_index(to.terminals, to_in.terminals, to_index);
        result.terminals.emplace_back(from_index, to_index);
      } else {
        from_index =
            original_index(from.junctions, from_in.junctions, from_index - from.num_terminals());
        to_index = original_index(to.junctions, to_in.junctions, to_index - to.num_terminals());
        result.junctions.emplace_back(from_index, to_index);
      }
    }
    results.push_back(std::move(result));
  }
  return results;
}

}  // namespace vb::morph
