#pragma once

#include <Eigen/Core>

#include "morph/articulated_fit.h"
#include "morph/embedded_deformation.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"
#include "morph/template_model.h"
#include "morph/worker_pool.h"

namespace vb::morph {

/// Node transforms that turn the template's limbs as wholes about their roots onto the
/// target's limbs: a start for the posture fit (ArticulateTemplate) that closest points alone
/// cannot reach when a limb turned far, such as an arm raised over the head that would stay
/// on the flank it hung beside.
///
/// Each template branch of @p guide is paired with a target branch by PairBranches, at
/// options.limb_pair_fraction of their lengths, with the template at rest. A pair's rotation
/// is the least one that turns the template limb's axis onto the target limb's (each the
/// principal direction of its branch's samples along the shorter of the two, from the
/// root); the twist about the axis, which a limb's samples cannot tell, is left to the
/// posture fit. It turns every graph node of the template limb (TemplateLimbs::node_branch)
/// about the template branch's root, and is kept only when, with the placement, it brings
/// the limb's nodes nearer the target's points and the target limb's points
/// (BranchGuide::target_support) nearer the limb's nodes. The trunk and the limbs not turned
/// keep the identity.
///
/// @param[in] target 3 by N points in the target's frame, indexed by @p target_index; the
///   guide's target side is in the same frame.
/// @param[in] placement the template's normalised frame -> the target's.
/// @param[out] turned when given, the number of limbs turned.
/// @param current when given, the fit so far: a limb whose nodes it already has within
///   options.limb_swing_cap (mean distance) of where the turn would put them is left to it.
/// @pre the guide was made for @p model (MakeBranchGuide) and `placement.Usable()`.
DeformationState TurnLimbs(const TemplateModel& model, const BranchGuide& guide,
                           const Eigen::Matrix3Xd& target, const PointIndex& target_index,
                           const Similarity& placement, const ArticulationOptions& options,
                           int* turned = nullptr, const DeformationState* current = nullptr);

/// The swing about the limbs' roots alone, which SwingLimbs gives beside its own.
struct RootSwing {
  DeformationState state;
  int swung = 0;  ///< limbs moved
};

/// Node transforms from @p start with each template limb swung as a whole about its posed
/// root to the direction in which it best explains the target: the limb's axis (from its root
/// to the centroid of its samples) is laid on each of options.limb_swing_directions
/// directions spread over the sphere, by the least rotation, and the one kept leaves the least
/// two-way distance: from the limb's samples (of options.template_samples evenly spread over
/// the template) to the target's nearest points, and from the target's samples
/// (options.target_samples) to the template's, each distance capped at options.limb_swing_cap
/// template sizes.
/// Each limb is tried in two shapes: as @p start poses it, and in its rest shape, turned as
/// the graph node that weighs most at its root is (the nearest rotation of that node's
/// transform) and hung from the posed root, since a fit may have folded a limb along a
/// neighbour it lay on; the rest shape is also scored where it points, unswung. With
/// options.limb_swing_pivots above 1, the same is tried about points out along the limb's
/// branch, moving only the samples and graph nodes at least that far out
/// (TemplateLimbs::vertex_along, node_along), and the pivot whose best move lowers that two-way
/// distance most is kept. A limb moves only when
/// a move beats its own place and shape by more than rounding. Limbs go longest first, each
/// against the others as already moved. Unlike TurnLimbs it reads no skeleton of the target:
/// only the template's limbs (TemplateLimbs::vertex_branch, node_branch) and their roots.
/// @param[in] target 3 by N points in the target's frame, indexed by @p target_index.
/// @param[in] placement the template's normalised frame -> the target's.
/// @param[out] swung when given, the number of limbs moved (swung, or unfolded in place).
/// @param pool when given, the directions are scored on its threads (the same result on any
///   number of threads).
/// @param[out] beyond_root when given, how many of the limbs moved about a pivot beyond
///   their roots by options.limb_swing_cap or more (the mean over the graph nodes moved).
/// @param[out] about_roots when given, the swing as with options.limb_swing_pivots = 1,
///   made beside this one: the two share each limb's move about its root until a limb moves
///   about a pivot beyond.
/// @pre the guide was made for @p model (MakeBranchGuide) and `placement.Usable()`.
DeformationState SwingLimbs(const TemplateModel& model, const BranchGuide& guide,
                            const Eigen::Matrix3Xd& target, const PointIndex& target_index,
                            const Similarity& placement, const DeformationState& start,
                            const ArticulationOptions& options, int* swung = nullptr,
                            WorkerPool* pool = nullptr, int* beyond_root = nullptr,
                            RootSwing* about_roots = nullptr);

/// Node transforms from @p start (a posture fit) with template limbs turned onto the target
/// limbs it leaves uncovered: each target branch of @p guide whose supporting points
/// (BranchGuide::target_support, every (1 + count / 200)-th) nearest the outer half of its
/// samples (all of them when none are) lie farther than options.reclaim_uncovered from the template
/// posed by @p start, on average, most uncovered first, gets one template limb not yet moved: among
/// those whose posed root lies within options.reclaim_root of the target branch's samples, the one
/// whose outer half lies farthest from every target branch's samples (the root's distance less
/// that, least). That limb, in its rest shape, is turned by the least rotation that points its axis
/// (root to the mean of its samples) at the mean of the target branch's samples and hung from its
/// posed root; the trunk and the other limbs keep @p start's transforms.
/// @param[in] target 3 by N points in the target's frame (those the guide's support indexes).
/// @param[in] placement the template's normalised frame -> the target's.
/// @param[out] reclaimed the number of limbs turned (0: the state is @p start's).
/// @pre the guide was made for @p model (MakeBranchGuide) against @p target and
///   `placement.Usable()`.
DeformationState ReclaimLimbs(const TemplateModel& model, const BranchGuide& guide,
                              const Eigen::Matrix3Xd& target, const Similarity& placement,
                              const DeformationState& start, const ArticulationOptions& options,
                              int* reclaimed);

}  // namespace vb::morph
