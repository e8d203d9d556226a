#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "morph/embedded_deformation.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"
#include "morph/skeleton_branches.h"
#include "morph/template_model.h"

namespace vb::morph {

/// Rounds of the coarse stage's posture fit. Lengths are template sizes.
struct ArticulationOptions {
  /// Rounds of pairing -> trimming -> deformation, each from the previous pose.
  int rounds = 6;
  /// Template vertices and target points paired per round (evenly spread).
  int template_samples = 600;
  int target_samples = 600;
  /// Of the template's pairs, the nearest this fraction are kept (eq. 12's trimming, by
  /// distance): a region the target does not show (a camera shadow, a lost limb) has far
  /// partners only and does not pull. Also the trimming of ArticulationResult::disagreement.
  double keep_fraction = 0.8;
  /// Whether ArticulationResult::disagreement weighs each template sample by how unlike the
  /// template is to itself turned belly for back there (HalfTurnAsymmetry), and each target
  /// sample by its nearest posed sample's weight: what the coarse stage's choice between
  /// placements reads. false: every sample alike (TrimmedDisagreement).
  bool weigh_by_asymmetry = false;
  /// Of the target's pairs, the nearest this fraction are kept. All of them by default: the
  /// target shows part of the template's surface, so every target point has a partner on
  /// it, and the farthest are those of a limb the template has not yet reached, the pairs
  /// that move it there (docs/decisions.md: trimming them at 0.8 as the template's left
  /// the posture fit at the rigid floor).
  double target_keep_fraction = 1.0;
  /// w_rot, w_reg and w_rig start at the deformation options' values times this and are
  /// multiplied by stiffness_decay each round, down to min_stiffness: stiff first, so limbs
  /// turn as wholes, then free enough to bend at the joints.
  double stiffness_start = 1.0;
  double stiffness_decay = 0.5;
  double min_stiffness = 0.1;
  /// When the target's normals are given (ArticulateTemplate's target_normals), a pair is
  /// made only between surfaces facing alike: the partner is the nearest of the
  /// normal_candidates nearest points whose normal is within max_normal_angle_deg of the
  /// sample's, either sign (a cloud's estimated normals have none). A sample with no such
  /// partner makes no pair, and the trimming above keeps its fraction of the pairs made.
  /// Nearness alone pairs an arm with the flank it hangs beside. 90 turns it off; small
  /// angles leave few pairs (bounds in the profile: 1 to 90 degrees).
  double max_normal_angle_deg = 60.0;
  int normal_candidates = 8;
  /// AlignCoarse: neighbours per principal-axis normal of a target given without (usable)
  /// normals, estimated once per job for every candidate's fit.
  int normal_neighbours = 10;
  /// Limb ends: each round, the template's terminals (posed) and the target's are paired as
  /// mutual nearest within terminal_radius, and each pair pulls with terminal_weight times a
  /// surface pair's weight; closest points alone cannot tell which limb a tip belongs to
  /// once limbs have moved far. 0 turns it off.
  /// Off by default: measured on bench shapes it helped the humanoids' coarse stage and hurt
  /// the bison's and spider's (docs/decisions.md).
  double terminal_radius = 0.12;
  double terminal_weight = 0.0;
  /// Limbs along their skeleton branches (a BranchGuide given to ArticulateTemplate): each
  /// round the posed template's branches and the target's are paired where each is the
  /// other's cheapest, the cost being the distance between their roots plus that between
  /// their points three quarters of the way out, within branch_radius, and their lengths
  /// differ by at most branch_max_ratio times. A pair pulls the template branch's points a
  /// half, three quarters and all of the way along the shorter of the two onto the target
  /// branch's at the same arc lengths (a limb the shadow cut short pulls only as far as it is
  /// seen), with branch_weight times a surface pair's weight, multiplied by branch_decay each
  /// round. Surface pairs alone leave a limb that turned far at the nearest surface. 0 turns
  /// it off.
  double branch_weight = 2.0;
  double branch_decay = 0.5;
  double branch_radius = 0.4;
  double branch_max_ratio = 1.5;
  /// Limbs turned as wholes (TurnLimbs), for the chosen placement: its posture fit is run a
  /// second time, from the template with each limb turned about its root onto the paired
  /// target limb, and that fit is kept when its trimmed disagreement is below limb_turn_gain
  /// times the first's. Closest points cannot draw a limb that turned 90 degrees or more
  /// (an arm raised over the head stays on the flank it hung beside). 0 turns it off.
  double limb_turn_gain = 0.95;
  /// Limbs are paired for the turn by their roots and by their points this far out along
  /// their length (within branch_radius together, lengths within branch_max_ratio): near the
  /// root, so that a limb is found wherever it points, far enough to tell two limbs that
  /// share a root apart.
  double limb_pair_fraction = 0.25;
  /// Limbs swung (SwingLimbs), for the chosen placement, after its posture fit: each template
  /// limb is tried in this many directions spread over the sphere about its posed root, and
  /// the fit is run again from the limbs swung where the target is best explained; kept by
  /// the same rule as the turn (limb_turn_gain). Needs no skeleton of the target, so a limb
  /// the target's skeleton merged with its neighbour or cut at another junction still
  /// reaches its place. 0 turns it off.
  int limb_swing_directions = 96;
  /// How far apart a swung limb and the target count at most, template sizes: a limb the
  /// target does not show (a camera shadow) gains little by lying on some other surface.
  /// Also how near (mean over its nodes) the first fit must have a limb to where TurnLimbs
  /// would put it for that turn to be left out, the fit having done it; and how far (mean
  /// over the graph nodes moved) a swing about a pivot beyond a root must move a limb for the
  /// coarse stage to fit from it.
  double limb_swing_cap = 0.05;
  /// Points along a limb it is swung about (SwingLimbs): k / (limb_swing_pivots + 1) of its
  /// branch's length from the root (rounded to BranchGuide::kSamples), k = 0 .. pivots - 1,
  /// only the part from the pivot out moving. 1: the root alone. The coarse stage fits from
  /// the swing about the roots alone as well (AlignCoarse).
  int limb_swing_pivots = 4;
  /// Target limbs reclaimed (ReclaimLimbs), for the chosen placement, after its posture fit: a
  /// target limb (a branch of the target's skeleton) whose surface points along its outer
  /// half lie farther than reclaim_uncovered from the posed template on average, template
  /// sizes (a limb laid along the trunk covers the root and leaves the end), gets one template
  /// limb turned onto it: of those whose posed root lies within reclaim_root of its skeleton,
  /// the one whose root's distance less its outer half's distance from every target limb is
  /// least. The fit is run again from there and kept by the same rule as the turn
  /// (limb_turn_gain). Closest points leave a limb the fit laid on its
  /// neighbour's target limb there (two template fore legs on one target fore leg, the other
  /// bare), and neither the turn, which pairs limbs by their roots, nor the swing, which
  /// scores one limb's directions at a time, moves it off. 0 turns it off.
  double reclaim_uncovered = 0.04;
  double reclaim_root = 0.15;
  /// The data weight per graph node: each pair's weight is w_data times the node count over
  /// the pair count, so the balance with the regularisers does not depend on the sampling.
  EmbeddedDeformationOptions deformation{
      .w_data = 10.0, .max_iterations = 10, .function_tolerance = 1e-4, .deadline = {}};
};

/// Both skeletons' limbs (TerminalBranches), each sampled at kSamples evenly spaced arc
/// lengths from its root to its tip, for ArticulationOptions' branch pulls, TurnLimbs and
/// SwingLimbs: the template's made once (TemplateModel::limbs), the target's per target.
struct BranchGuide {
  static constexpr int kSamples = TemplateLimbs::kSamples;
  /// The column of sample @p k of branch @p b in the matrices below and in TemplateLimbs::rest.
  static Eigen::Index Column(int b, int k) {
    return static_cast<Eigen::Index>(b) * kSamples + k;
  }
  /// The sample nearest @p fraction of a branch's length from its root.
  static int SampleAt(double fraction) {
    return static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * (kSamples - 1)));
  }
  /// Template side, normalised frame: the model's own (none in a guide made empty).
  const TemplateLimbs* limbs = nullptr;
  /// Target side, in the target's frame and units: kSamples columns per branch, root first.
  Eigen::Matrix3Xd target_points;
  std::vector<double> target_length;
  /// Per target branch: the target points its skeleton nodes stand for, its root's left out.
  std::vector<std::vector<int>> target_support;
  int num_template_branches() const { return limbs != nullptr ? limbs->num_branches() : 0; }
  int num_target_branches() const { return static_cast<int>(target_length.size()); }
};

/// The guide's target branch samples (BranchGuide::target_points) carried by @p to_template
/// (the target's frame -> the template's normalised frame), column for column.
Eigen::Matrix3Xd TargetBranchesIn(const BranchGuide& guide, const Similarity& to_template);

/// Evenly spread column indices of a matrix with @p n columns, about @p wanted of them (every
/// n / wanted-th, from the first).
std::vector<int> Spread(Eigen::Index n, int wanted);

/// About @p wanted template vertices, evenly spread (Spread), with their rest positions
/// (normalised frame) and eq. (10) node weights, as the posture fit pairs them.
struct TemplateSamples {
  std::vector<int> ids;
  Eigen::Matrix3Xd rest;  ///< 3 by #ids
  NodeWeights weights;    ///< of each column of rest
};
TemplateSamples SampleTemplate(const TemplateModel& model, int wanted);

/// The guide between @p model's limbs and a target's (@p target_skeleton and the
/// @p target_features extracted from it, in the target's frame). @pre @p model outlives the
/// guide.
BranchGuide MakeBranchGuide(const TemplateModel& model, const SkeletonGraph& target_skeleton,
                            const FeatureNodes& target_features);

/// Branch pairs (template, target) that are each other's cheapest: the cost is the distance
/// between their roots plus that between their points @p along their lengths out, within
/// options.branch_radius, for lengths within options.branch_max_ratio of each other.
/// @param[in] posed the template's branch samples (TemplateLimbs::rest, as posed).
/// @param[in] target the target's branch samples brought into the template's frame.
/// @param scale target units per template size.
std::vector<std::pair<int, int>> PairBranches(const BranchGuide& guide,
                                              const Eigen::Matrix3Xd& posed,
                                              const Eigen::Matrix3Xd& target, double scale,
                                              double along, const ArticulationOptions& options);

/// A pose of the template and how well it covers the target.
struct ArticulationResult {
  bool ok = false;
  DeformationState state;
  /// Trimmed two-way disagreement after the last round: mean of the kept closest-point
  /// distances (TrimmedDisagreement), weighted by the template's asymmetry when
  /// ArticulationOptions::weigh_by_asymmetry (WeightedTrimmedDisagreement), template sizes.
  double disagreement = 0.0;
  /// How far the pose bends the template: the mean distance of the posed samples from the
  /// best similarity image of their rest positions, template sizes.
  double bend = 0.0;
  int rounds = 0;
  double seconds = 0.0;
};

/// The pairs (i, j) of columns of @p a and @p b that are each other's nearest and lie within
/// @p radius.
std::vector<std::pair<int, int>> MutualNearestPairs(const Eigen::Matrix3Xd& a,
                                                    const Eigen::Matrix3Xd& b, double radius);

/// How far apart two point sets are, robust to parts one of them lacks: the mean of the
/// nearest @p keep_fraction of the distances from each column of @p a to the points
/// @p b_index holds, and likewise from each column of @p b_samples to those @p a_index
/// holds, averaged. In the points' units.
double TrimmedDisagreement(const Eigen::Matrix3Xd& a, const PointIndex& a_index,
                           const Eigen::Matrix3Xd& b_samples, const PointIndex& b_index,
                           double keep_fraction);

/// How unlike a shape is to itself turned half round about its longest principal axis, per
/// sample: for each column of @p samples, the distance from its image under that half turn
/// (about the samples' mean) to the nearest column. About the samples' spacing where the
/// turn maps the shape onto itself (a trunk round in section, a limb with a partner
/// opposite), large where it would not (a face, feet, a tail). In the samples' units.
/// @pre at least one column.
std::vector<double> HalfTurnAsymmetry(const Eigen::Matrix3Xd& samples);

/// TrimmedDisagreement with weights: the nearest @p keep_fraction of the distances each way
/// are kept as there, then averaged with the weight @p a_weights gives each column of @p a,
/// and, from @p b_samples, the weight of its nearest column of @p a. Weights summing to zero
/// on a side count every kept distance alike. @pre a_weights.size() == a.cols(), none negative.
double WeightedTrimmedDisagreement(const Eigen::Matrix3Xd& a, const PointIndex& a_index,
                                   const std::vector<double>& a_weights,
                                   const Eigen::Matrix3Xd& b_samples, const PointIndex& b_index,
                                   double keep_fraction);

/// Non-rigid closest-point fitting of the template's posture to a placed target: each round
/// pairs template samples with their nearest target points and target samples with their
/// nearest template samples (given normals, the nearest facing alike), keeps the nearest
/// pairs of each side, and solves the embedded deformation (eqs. 4-10) with them as point
/// constraints, starting from @p start. The fit is in the template's normalised frame; the
/// target stays in its own, so one kd-tree of it serves every placement tried.
/// @param[in] target 3 by N points in the target's frame; @p target_index indexes them.
/// @param[in] target_terminals 3 by T limb ends of the target's skeleton, in the target's
///   frame (may be empty).
/// @param[in] placement the template's normalised frame -> the target's. A similarity keeps
///   nearest points nearest, so the fit is the same as on a target moved into the template's
///   frame. Pass `Similarity{}` for a target already there.
/// @param guide the skeletons' limbs, for options.branch_weight (none: no branch pulls).
/// @param target_normals 3 by N unit normals of @p target, in its frame, of either sign (zero:
///   no direction known, compatible with any), for options.max_normal_angle_deg. None, or a
///   template without vertex normals: pairs by nearness alone.
/// @pre `placement.Usable()` and `placement.R` is a rotation.
ArticulationResult ArticulateTemplate(
    const TemplateModel& model, const Eigen::Matrix3Xd& target, const PointIndex& target_index,
    const Eigen::Matrix3Xd& target_terminals, const DeformationState& start,
    const ArticulationOptions& options, const Similarity& placement,
    const BranchGuide* guide = nullptr, const Eigen::Matrix3Xd* target_normals = nullptr);

}  // namespace vb::morph
