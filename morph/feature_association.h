#pragma once

#include <Eigen/Core>
#include <Eigen/SVD>
#include <cmath>
#include <utility>
#include <vector>

#include "morph/skeleton_graph.h"

namespace vb::morph {

/// A similarity transform x -> scale * R * x + t.
struct Similarity {
  double scale = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator()(const Eigen::Vector3d& x) const { return scale * (R * x) + t; }
  /// From the 4x4 result of Eigen::umeyama with scaling.
  static Similarity FromUmeyama(const Eigen::Matrix4d& T);
  Similarity Inverse() const { return {1.0 / scale, R.transpose(), -(R.transpose() * t) / scale}; }
  /// Whether a placement can be built on it: a positive finite scale and finite R and t
  /// (degenerate point sets, all in one spot, give a zero or non-finite scale).
  bool Usable() const {
    return std::isfinite(scale) && scale > 0 && R.allFinite() && t.allFinite();
  }
};

/// The similarity x -> a(b(x)).
inline Similarity Compose(const Similarity& a, const Similarity& b) {
  return {a.scale * b.scale, a.R * b.R, a.scale * (a.R * b.t) + a.t};
}

/// The rotation R maximising trace(R^T M) for a 3x3 correlation M = sum_i w_i b_i a_i^T (so R
/// takes the a_i nearest to the b_i: Kabsch's and Wahba's problem), from M's SVD given as
/// @p svd (with full U and V): U diag(1, 1, +-1) V^T, the sign making it a rotation.
Eigen::Matrix3d NearestRotation(const Eigen::JacobiSVD<Eigen::Matrix3d>& svd);

/// The chosen pairing of feature nodes between two skeletons (eq. 3).
struct Association {
  bool ok = false;
  std::vector<std::pair<int, int>> terminals;  ///< (index in `from`, index in `to`)
  std::vector<std::pair<int, int>> junctions;
  /// Best fit of the paired nodes, `from` -> `to` (in AlignCoarse's result: the placement
  /// chosen, refined and refitted, CoarseResult::placement and ::refit composed).
  Similarity from_to;
  double rms_residual = 0.0;  ///< of that fit per residual degree of freedom, with the penalty for
                              ///< unpaired features; `to` units
  long candidates = 0;        ///< pairings whose fit was evaluated
  long pruned = 0;            ///< partial pairings cut by distance ratios
};

struct AssociationOptions {
  /// Two paired segments may not change length by more than this factor relative to each
  /// other (a carcass bends, it does not stretch a leg to twice its length).
  double max_relative_stretch = 2.5;
  /// More candidates than this: the feature sets are trimmed to their most extreme nodes.
  long max_candidates = 300'000;
  /// How many of the best pairings to return (distinct, best first), for verification.
  int keep_best = 64;
  /// Pairings whose fit turns from_up to less than min_cos_up with to_up are not kept
  /// (the coarse stage's upright prior; min_cos_up = -1 keeps every orientation). Unit
  /// vectors.
  Eigen::Vector3d from_up = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d to_up = Eigen::Vector3d::UnitZ();
  double min_cos_up = -1.0;

  /// Whether a fit with rotation @p R keeps from_up within the allowed tilt of to_up.
  bool AcceptsOrientation(const Eigen::Matrix3d& R) const {
    return min_cos_up <= -1.0 || (R * from_up).dot(to_up) >= min_cos_up;
  }
};

/// Exhaustive search for the feature correspondence that minimises eq. (3): every
/// injective pairing of terminals with terminals and junctions with junctions (the smaller
/// set of each kind paired, but for at most one terminal and one junction left out, since
/// real skeletons grow spurs and merge limbs) is scored by the residual per pair of its
/// closed-form similarity fit (Umeyama, with scale since carcasses differ in size);
/// partial pairings whose terminal-to-terminal distances cannot come from one similarity
/// (up to max_relative_stretch) are cut.
/// Returns up to options.keep_best pairings, lowest residual first; empty when fewer than
/// three pairs are possible. Every returned Association has ok = true and shares the
/// candidate counts of the whole search.
std::vector<Association> AssociateFeatureNodes(const FeatureNodes& from, const FeatureNodes& to,
                                               const AssociationOptions& options = {});

}  // namespace vb::morph
