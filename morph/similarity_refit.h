#pragma once

#include <Eigen/Core>

#include "morph/feature_association.h"
#include "morph/worker_pool.h"

// The coarse stage's last step: the posed template moved as a whole (a similarity) onto the
// target, fitted from the target's side.
namespace vb::morph {

struct SimilarityRefitOptions {
  /// Rounds of pairing and fitting; 0: off (the identity).
  int rounds = 6;
  /// Target points paired a round, at most (every n-th of the target).
  int samples = 3000;
  /// The nearest this share of the pairs is fitted (the rest, parts of the target the
  /// template does not reach, such as clutter or a limb it lacks, left out).
  double keep_fraction = 0.95;
};

/// The similarity S (the target's frame to itself) bringing @p posed onto @p target as seen
/// from the target: each round pairs up to `samples` target points (every n-th) with their
/// nearest point of S(posed), keeps the nearest keep_fraction of the pairs and fits S to them
/// (Umeyama's closed form, with scale), from the start each round. Why from the target's
/// side: docs/method.md section 2.7.
/// @param[in] posed, target 3 by N points in the same frame (any unit); non-finite target
///   points are skipped. Clutter beyond 1 - keep_fraction of the target biases the fit.
/// @pre 0 < options.keep_fraction <= 1.
/// @param pool when given, the pairing is shared among its threads; the result is the same on
///   any number of threads.
/// @return the identity when rounds or samples is below 1, when posed has fewer than 4 points
///   or fewer than 4 target points are finite among those sampled, or when
///   the first fit is degenerate (not finite, or scaling by less than 1/2 or more than 2: a
///   collapse onto a target all in one spot or on one line); a later degenerate fit ends the
///   rounds with the last good one.
Similarity RefitSimilarity(const Eigen::Matrix3Xd& posed, const Eigen::Matrix3Xd& target,
                           const SimilarityRefitOptions& options, WorkerPool* pool = nullptr);

}  // namespace vb::morph
