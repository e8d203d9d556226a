#pragma once

#include <Eigen/Core>

#include "morph/articulated_fit.h"
#include "morph/embedded_deformation.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"
#include "morph/template_model.h"

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
/// posture fit. It turns every graph node of the template limb (BranchGuide::node_branch)
/// about the template branch's root, and is kept only when, with the placement, it brings
/// the limb's nodes nearer the target's points and the target limb's points
/// (BranchGuide::target_support) nearer the limb's nodes. The trunk and the limbs not turned
/// keep the identity.
///
/// @param[in] target 3 by N points in the target's frame, indexed by @p target_index; the
///   guide's target side is in the same frame.
/// @param[in] placement the template's normalised frame -> the target's.
/// @param[out] turned when given, the number of limbs turned.
/// @pre the guide was made for @p model (MakeBranchGuide) and `placement.Usable()`.
DeformationState TurnLimbs(const TemplateModel& model, const BranchGuide& guide,
                           const Eigen::Matrix3Xd& target, const PointIndex& target_index,
                           const Similarity& placement, const ArticulationOptions& options,
                           int* turned = nullptr);

}  // namespace vb::morph
