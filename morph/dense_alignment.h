#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "io/triangle_mesh.h"
#include "morph/coarse_alignment.h"
#include "morph/dense_association.h"
#include "morph/embedded_deformation.h"
#include "morph/template_model.h"

namespace vb::morph {

/// Section II-B. Lengths are fractions of the template's size (its normalised frame).
struct DenseOptions {
  /// Template vertices associated per round (every n-th vertex; all when the mesh is smaller).
  int num_samples = 2000;
  /// Neighbours for the principal-axis normals of a target given without normals.
  int normal_neighbours = 24;
  /// Each associated target point is replaced by the centroid of this many nearest target
  /// points, which averages sensor noise along the normal (measured at sigma 16 mm: mean
  /// error 21 -> 17 mm); few, so curved limbs are not flattened (24 cost 0.02 in volume
  /// RMSE at sigma 0).
  int surface_neighbours = 10;
  /// Noise level at which the data weight halves. The noise is estimated from the target
  /// itself (1.4826 x the median offset of its points from their neighbours' centroid along
  /// the normal; it reads about half the true sigma, since the local plane absorbs some), and
  /// the data term is weighted by 1 / (1 + (noise / noise_reference)^2). Measured on 6 lamb
  /// targets: cut-plane distance at sigma 4 mm 6.8 -> 4.5 mm, at sigma 16 11.5 -> 10.0 mm,
  /// unchanged at sigma 0.
  double noise_reference = 0.002;
  DenseAssociationOptions association;
  AssociationFilterOptions filter;
  /// Rounds of association -> filtering -> deformation, each from the previous result.
  int rounds = 5;
  /// w_rot and w_reg are multiplied by this each round (a stiff start that cannot fold, then
  /// freedom to follow the surface's own features). Measured on 10 lamb targets x sigma
  /// {0, 4, 16}, meshes and partial clouds: against 3 rounds at constant stiffness, cut-plane
  /// distance at sigma 4 mm 4.5 -> 3.9 mm (meshes), 6.3 -> 5.0 mm (clouds) and volume RMSE
  /// 0.064 -> 0.030 (meshes), for about 0.15 s more. Adding a point-to-point term beside
  /// point-to-plane (weight 0.1 or 0.3) made every figure worse: nearest-point pairs slide.
  double stiffness_decay = 0.6;
  /// Eq. (13). w_data is per graph node: it is divided by the number of associations per
  /// node, so its balance with the regularisers does not depend on num_samples.
  EmbeddedDeformationOptions deformation{
      .w_data = 100.0,
      .max_iterations = 20,
      .linear_solver = EmbeddedDeformationOptions::LinearSolver::kConjugateGradients};
};

struct DenseRound {
  int associated = 0;                ///< pairs found by eq. (11)
  int kept = 0;                      ///< left after eq. (12)
  double mean_plane_distance = 0.0;  ///< of the kept pairs before the solve, template sizes
  SolveSummary deformation;
  double association_seconds = 0.0;
  double filter_seconds = 0.0;
};

struct DenseResult {
  bool ok = false;
  std::string error;
  io::TriangleMesh mesh;            ///< morphed template in the target's frame (template faces)
  DeformationState state;           ///< normalised template frame
  Eigen::Matrix3Xd target_normals;  ///< unit, target frame; given or estimated
  std::vector<DenseRound> rounds;
  double noise = 0.0;  ///< estimated sensor noise (standard deviation), template sizes
  double normals_seconds = 0.0;
  double total_seconds = 0.0;
};

/// Dense surface alignment after the coarse stage: dense normal-aware association (eq. 11),
/// rigidity filtering (eq. 12) and point-to-plane embedded deformation (eqs. 13-14), on the
/// template's deformation graph, starting from the coarse node transforms.
/// @param[in] target 3 by N points in the target's frame (as given to AlignCoarse).
/// @param[in] target_normals 3 by N unit outward normals, or empty to estimate them.
DenseResult AlignDense(const TemplateModel& model, const CoarseResult& coarse,
                       const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& target_normals,
                       const DenseOptions& options = {});

}  // namespace vb::morph
