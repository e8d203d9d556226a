#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "morph/deformation_graph.h"
#include "morph/skeleton_graph.h"

namespace vb::morph {

/// Lengths are fractions of the template's bounding-box diagonal.
struct TemplateModelOptions {
  /// Where the template's skeleton comes from: the same level-set skeleton the targets get
  /// (applied to the template's vertices), which places junctions and limb ends the same
  /// way on both sides; or its mean curvature flow skeleton, as in the paper (see
  /// docs/method.md, "Skeletons"). Either is reproducible; a template model is still computed
  /// once and stored, not recomputed per run.
  enum class FeatureSource { kLevelSet, kMeanCurvatureFlow };
  FeatureSource feature_source = FeatureSource::kLevelSet;
  /// Spur and junction thresholds. Shorter spurs than the targets' (CoarseOptions): the
  /// template is clean, and a short limb such as a lamb's neck must survive.
  FeatureOptions features{.min_branch_length = 0.05, .junction_merge_distance = 0.08};
  DeformationGraphOptions graph;
};

/// The template's limbs (TerminalBranches of its skeleton), each sampled at kSamples evenly
/// spaced arc lengths from its root to its tip, and the limb each vertex and graph node lies
/// on: what the posture fit's branch pulls, TurnLimbs and SwingLimbs read of the template.
/// Derived from the model's skeleton, features, graph and weights (MakeTemplateLimbs) when it
/// is built or loaded; not stored.
struct TemplateLimbs {
  static constexpr int kSamples = 21;
  /// Normalised frame: kSamples columns per limb, root first.
  Eigen::Matrix3Xd rest;
  NodeWeights weights;         ///< eq. (10) weights of those points
  std::vector<double> length;  ///< per limb, template sizes
  /// Per deformation-graph node: the limb it lies on (-1: the trunk, or a root).
  std::vector<int> node_branch;
  /// Per template vertex: the limb it lies on (-1: the trunk).
  std::vector<int> vertex_branch;
  /// Per template vertex on a limb: how far out along its limb the skeleton node that stands
  /// for it lies, a fraction of the limb's length (0 on the trunk).
  std::vector<double> vertex_along;
  /// Per deformation-graph node, likewise (its vertex's).
  std::vector<double> node_along;
  int num_branches() const { return static_cast<int>(length.size()); }
};

/// Everything about a template that does not depend on the target, computed once (offline,
/// then loaded by the daemon): libigl's precomputation half. All positions are in the
/// template's normalised frame, x_hat = (x - centre) / size, so every threshold is
/// relative to the template's size.
struct TemplateModel {
  geometry::TriangleMesh mesh;  ///< as given (original units), with normals
  Eigen::Vector3d centre;       ///< bounding-box centre
  double size = 1.0;            ///< bounding-box diagonal
  Eigen::Matrix3Xd V;           ///< normalised vertex positions
  SkeletonGraph skeleton;       ///< the skeleton the features come from, normalised
  FeatureNodes features;        ///< pruned terminals and junctions, normalised
  DeformationGraph graph;       ///< on the normalised mesh
  NodeWeights vertex_weights;
  NodeWeights terminal_weights;
  TemplateLimbs limbs;   ///< derived from the above (MakeTemplateLimbs)
  double seconds = 0.0;  ///< time to build

  Eigen::Vector3d Normalise(const Eigen::Vector3d& x) const { return (x - centre) / size; }
  Eigen::Vector3d Denormalise(const Eigen::Vector3d& x) const { return x * size + centre; }
};

/// Builds the model. @throws InputError naming the defect when the mesh is not a closed,
/// consistently oriented, connected 2-manifold, or its skeleton has fewer than three
/// feature nodes.
/// The feature source named @p name: "levelset" or "mcf".
/// @throws InputError naming @p where (e.g. a command's option) and the value otherwise.
TemplateModelOptions::FeatureSource FeatureSourceNamed(const std::string& name,
                                                       const std::string& where);

TemplateModel BuildTemplateModel(const geometry::TriangleMesh& mesh,
                                 const TemplateModelOptions& options = {});

/// @p model's limbs, from its skeleton, features, graph, vertex weights and V. A vertex, and
/// so a graph node, lies on the limb whose skeleton nodes (its root's left out) stand for it;
/// one two limbs share goes to the first.
TemplateLimbs MakeTemplateLimbs(const TemplateModel& model);

}  // namespace vb::morph
