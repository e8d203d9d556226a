#pragma once

#include <Eigen/Core>
#include <string>

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

}  // namespace vb::morph
