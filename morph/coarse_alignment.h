#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "morph/articulated_fit.h"
#include "morph/cloud_skeleton.h"
#include "morph/embedded_deformation.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"
#include "morph/similarity_refit.h"
#include "morph/skeleton_graph.h"
#include "morph/template_model.h"
#include "morph/worker_pool.h"

namespace vb::morph {

/// What the line knows about how a carcass hangs: the template's up direction (its frame)
/// must map to within max_tilt_deg of the target's up (the rig frame). Placements outside
/// are not considered, which rules out upside-down fits of a carcass that lost a limb to
/// occlusion.
struct UprightPrior {
  /// Off: any orientation (the method's default: targets come in any pose). A flag rather
  /// than std::optional, whose copies GCC 12 calls uninitialised under -O3 sanitizer builds.
  bool enabled = false;
  Eigen::Vector3d template_up = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d target_up = Eigen::Vector3d::UnitZ();
  double max_tilt_deg = 45.0;
};

struct CoarseOptions {
  CloudSkeletonOptions skeleton;
  /// For the target's skeleton, fractions of the target's size. Level-set branches run to
  /// the tips and noise grows short spurs, so the spur threshold is longer than the
  /// template's.
  FeatureOptions features{.min_branch_length = 0.09, .junction_merge_distance = 0.08};
  AssociationOptions association;
  /// Samples per side when checking candidate pairings against the surfaces.
  int verification_samples = 400;
  UprightPrior upright;
  /// The candidates with the least surface disagreement that are refined by closest-point
  /// similarity fitting (this many rounds each) before the final choice; 0 rounds: none.
  int refine_candidates = 8;
  int refine_iterations = 8;
  /// Also try the 24 placements laying the template's principal axes on the target's,
  /// refined the same way, beside the skeleton pairings.
  bool frame_candidates = true;
  /// Keep the embedded deformation only when it brings the surfaces closer than the rigid
  /// placement (CoarseResult::deformation_kept).
  bool check_deformation = true;
  /// After the placement is chosen, features are paired again as mutual nearest neighbours
  /// within this distance (template sizes); 0 keeps the chosen candidate's own pairs.
  double repair_radius = 0.12;
  /// Candidates whose rotations differ by more than this are different placements.
  double distinct_angle_deg = 30.0;
  EmbeddedDeformationOptions deformation;
  /// The best this many distinct placements (by rigid disagreement) are each given the
  /// posture fit (ArticulateTemplate) and the one that then fits the target best is chosen;
  /// 0: the rigid choice and the terminal-driven deformation alone.
  int articulated_candidates = 4;
  /// The best of those placements turned half round about the template's longest principal
  /// axis (1) and also its shortest (2), refined, join them when distinct: the front-for-back
  /// and upside-down turns a placement confuses, which the candidates above may all miss
  /// when the pose changed far. 0: none.
  int turned_candidates = 2;
  /// Rounds of the posture fit on each candidate before the choice; the chosen one is then
  /// fitted for all of `articulation.rounds`.
  int choice_rounds = 3;
  /// The choice reads each placement's posture fit weighted by the template's asymmetry
  /// under a half turn (ArticulationOptions::weigh_by_asymmetry): the parts that tell a body
  /// from itself turned belly for back count most. false: every part alike.
  bool choice_by_asymmetry = true;
  ArticulationOptions articulation;
  /// The posed template's last move, as a whole, fitted from the target's side; not applied
  /// when it would tilt the template past the upright prior's limit.
  SimilarityRefitOptions refit;
};

/// A placement the coarse stage's choice compared.
struct PlacementChoice {
  /// Its rotation, the template's normalised frame to the target's (Similarity::R): the
  /// placement before any posture fit.
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  /// Its score when the choice was made, as CoarseResult::choice_disagreement is measured:
  /// the trimmed disagreement after the choice's posture-fit rounds (weighted by the
  /// template's asymmetry when CoarseOptions::choice_by_asymmetry), template sizes; when no
  /// candidate was fitted, the rigid disagreement in target units over the chosen
  /// placement's scale.
  double disagreement = 0.0;
};

/// The outcome of the coarse stage. Expected trouble (a skeleton with too few feature nodes,
/// a solver failure) is reported in `ok`/`error`, never thrown.
struct CoarseResult {
  bool ok = false;
  std::string error;
  geometry::TriangleMesh mesh;    ///< posed template in the target's frame (template faces)
  /// The placement (from the feature association and the surfaces), refitted at the end
  /// (CoarseOptions::refit); template units to the target's.
  Similarity template_to_target;
  /// association.from_to (the template's normalised frame to the target's) is refit
  /// composed with placement.
  Association association;
  /// The placement chosen, before the refit (normalised frame to the target's).
  Similarity placement;
  /// The refit, the target's frame to itself (the identity when off or not applied).
  Similarity refit;
  /// Whether the chosen placement came from a skeleton pairing (else from the principal
  /// axes; its feature pairs are then the mutual nearest ones).
  bool placed_by_skeletons = true;
  FeatureNodes target_features;  ///< in the target's frame
  SolveSummary deformation;
  /// False when the deformation moved the template away from the target's surface and the
  /// rigid placement was kept instead.
  bool deformation_kept = true;
  /// Limbs the posture fit turned, swung or reclaimed as wholes before fitting again
  /// (TurnLimbs, SwingLimbs, ReclaimLimbs), when that fit was kept; 0 otherwise.
  int limbs_turned = 0;
  /// EstimateNormals' passes of the target normals the chosen placement's posture fit paired
  /// with (AlignCoarse's fit_normal_passes when it estimated them; 1 otherwise).
  int posture_normal_passes = 1;
  /// The node transforms found, in the template's normalised frame; the dense stage goes on
  /// from them.
  DeformationState state;
  /// Surface disagreement (mean closest-point distance both ways, template sizes) of the
  /// chosen placement after the whole posture fit (the rigid placement's when no candidate
  /// was given the posture fit), before the refit.
  double disagreement = 0.0;
  /// The chosen placement's disagreement when it was chosen: after the choice's rounds of
  /// posture fit (weighted as PlacementChoice::disagreement, so not comparable with
  /// `disagreement`), or rigid when no candidate was fitted. 0 when nothing was chosen.
  double choice_disagreement = 0.0;
  /// The least disagreement, measured as choice_disagreement is, of a candidate turned at
  /// least CoarseOptions::distinct_angle_deg from the chosen one: infinity when there is
  /// none, 0 when nothing was chosen. Close to choice_disagreement, the skeletons and
  /// surfaces could not tell two placements apart.
  double runner_up_disagreement = 0.0;
  /// Every placement the choice compared, the chosen one among them, in the order they were
  /// proposed: those whose choice rounds of posture fit succeeded, or every candidate when
  /// none was fitted. Empty when nothing was chosen. For reports and for the shape
  /// benchmark's account of turned placements (how near the truth the nearest one lay and how
  /// it scored).
  std::vector<PlacementChoice> choices;
  double skeleton_seconds = 0.0;
  double association_seconds = 0.0;
  double deformation_seconds = 0.0;
  double total_seconds = 0.0;
};

/// Section II-A: skeleton of the target cloud, feature association (eq. 3) and embedded
/// deformation of the template (eqs. 4-10) so its posture matches the target's.
/// @param[in] target 3 by N points (a cloud, or a mesh's vertices).
/// @param pool when given, the candidate placements' scoring, rigid refinement and posture
///   fits share its threads; the result is the same on any number of threads.
/// @param target_index a kd-tree over @p target the caller already has (none: one is built).
/// @param target_normals 3 by N normals of @p target, of any sign and length; a zero or
///   non-finite column means no direction known there. None, or another column count: the
///   posture fit estimates its own from the points.
/// @param fit_normal_passes when the posture fit estimates its own normals: the candidates'
///   fits, which choose the placement, pair with normals of one pass of
///   ArticulationOptions::normal_neighbours; the chosen placement's fit from there on with
///   normals of this many passes (EstimateNormals), which a noisy cloud needs
///   (CleanAndAlignCoarse sets it from the cloud's noise). @pre at least 1.
CoarseResult AlignCoarse(const TemplateModel& model, const Eigen::Matrix3Xd& target,
                         const CoarseOptions& options = {}, WorkerPool* pool = nullptr,
                         const PointIndex* target_index = nullptr,
                         const Eigen::Matrix3Xd* target_normals = nullptr,
                         int fit_normal_passes = 1);

}  // namespace vb::morph
