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
  /// Noisier targets widen that neighbourhood (EstimateNormals' passes) to about
  /// normal_neighbours x (noise / surface_noise)^2 points, up to max_normal_passes times it.
  /// A tilted plane has a part along the surface, so noisy normals slide the template.
  /// Measured on 10 lamb clouds with missing regions (`bench full --pairs 10 --sigmas-mm
  /// 0,2,4,8,16 --clouds --rig`), cut-plane distance at sigma 8 / 16 mm 4.71 / 10.82 -> 3.02 /
  /// 5.54 mm, volume RMSE 0.052 / 0.119 -> 0.038 / 0.072 (seed 2 at 16 mm, with the 64
  /// plane-point neighbours below, 13.96 -> 6.64 mm);
  /// sigma <= 4 and the rig unchanged (one pass there; two or three passes at sigma <= 4 made
  /// clouds at 4 mm 2.04 -> 2.13 / 2.22). A target's own normals (a mesh's faces) are kept:
  /// replaced by these, meshes at sigma 16 went 0.073 -> 0.043 in volume RMSE on seed 1 but
  /// 0.083 -> 0.115 on seed 2, with cut distance 4.40 -> 6.02 mm.
  int max_normal_passes = 8;
  /// Each associated target point is replaced by the centroid of this many nearest target
  /// points, which averages sensor noise along the normal (measured at sigma 16 mm: mean
  /// error 21 -> 17 mm); few, so curved limbs are not flattened (24 cost 0.02 in volume
  /// RMSE at sigma 0). This is the count for targets no noisier than surface_noise.
  int surface_neighbours = 10;
  /// Noisier targets average more points, surface_neighbours x (noise / surface_noise)^2,
  /// so that their plane points keep the noise of a target at surface_noise, up to
  /// max_surface_neighbours (past that, limbs flatten). Measured on 10 lamb targets, with
  /// the noise estimate below: cut-plane distance at sigma 8 / 16 mm 3.22 / 4.02 -> 3.02 /
  /// 3.78 mm (meshes) and 5.87 / 11.47 -> 5.59 / 11.29 mm (clouds with missing regions),
  /// unchanged at sigma <= 4. The cap was 32 while normals came from 24 points (more
  /// flattened the limbs); with normals that average as much as the noise asks (see
  /// max_normal_passes), 64: clouds at sigma 8 / 16 mm 3.02 / 5.54 -> 2.97 / 5.28 mm, volume
  /// RMSE at 16 0.072 -> 0.065, meshes and sigma <= 4 within 0.03 mm.
  double surface_noise = 0.0035;
  int max_surface_neighbours = 64;
  /// Plane points average no farther than this (coarse meshes: a few thousand vertices).
  double surface_radius = 0.03;
  /// The noise estimate (EstimateNoise): about noise_samples target points, each against a
  /// quadratic fitted to its noise_neighbours nearest within noise_radius.
  int noise_samples = 1000;
  int noise_neighbours = 60;
  double noise_radius = 0.03;
  /// A target so dense that its noise estimate had to be read at every n-th point (its
  /// nearest neighbours reached under about 4 sigma) is used at every n-th point, here and
  /// in the check and cut transfer after (DenseResult::target): the neighbourhoods of the
  /// normals and plane points, counted in points, then reach beyond the noise as they do on
  /// a sparser cloud. Measured on 10 lamb clouds with missing regions (`bench full --pairs 10
  /// --sigmas-mm 0,2,4,8,16 --clouds --cloud-points N`), cut-plane distance at 60,000 points,
  /// sigma 4 / 8 / 16 mm: 2.98 / 3.67 / 12.67 mm before (the estimate read half the noise at
  /// 16), 5.94 at 16 with the estimate that thins alone, 2.19 / 3.05 / 5.02 thinning the
  /// target too; 20,000 points 2.14 / 3.02 / 4.93 -> 2.14 / 3.02 / 5.01; 8,000 unchanged.
  bool thin_to_noise = true;
  /// Noise level at which the data weight halves: the data term is weighted by
  /// 1 / (1 + (noise / noise_reference)^2), a maximum-likelihood weighting. Measured on 6
  /// lamb targets: cut-plane distance at sigma 4 mm 6.8 -> 4.5 mm, at sigma 16 11.5 -> 10.0
  /// mm, unchanged at sigma 0. With the noise estimate that reads the true sigma (it read a
  /// third of it at sigma 16 mm before), on 10 lamb targets: sigma 16 mm meshes 4.33 -> 4.02
  /// mm, clouds with missing regions at sigma 8 / 16 mm 8.04 / 14.72 -> 5.87 / 11.47 mm,
  /// unchanged at sigma <= 4.
  double noise_reference = 0.0026;
  /// Each plane point (the centroid above) is moved along the normal by the mean offset of its
  /// neighbours' points from their own centroids. A centroid lies inside a convex surface by
  /// about the curvature times the neighbourhood's squared radius; on a tapered body that
  /// inward pull is satisfied by sliding the template along the taper, which moved cut lines.
  /// The correction keeps the noise averaging. Measured on 10 lamb meshes, sigma 0 / 16 mm:
  /// part-volume RMSE 0.023 -> 0.017 and 0.092 -> 0.071 (with the two changes below).
  bool correct_plane_offset = true;
  /// Each plane point is moved out along its normal by sigma^2 times the sum of the posed
  /// template's principal curvatures at the paired vertex (sigma the estimated noise; at most
  /// sigma). The morph shrank with the noise: every part's volume was 2-3 % small at sigma 8 mm
  /// and 5-7 % at 16, on meshes and clouds and both seeds. sigma^2 (k1 + k2) is how far a
  /// ball's centroid sits towards the concave side of a noisy surface (the points pushed
  /// there crowd); PlanePoints' correction removes only part of it (on a unit sphere and
  /// cylinder at sigma 0.01-0.04, 30-80 %). The full amount is used, not a fitted share:
  /// the mean part error went to within 2 % of zero (+0.2 to +2 %). Measured (`bench full
  /// --pairs 10 --sigmas-mm 0,2,4,8,16 --clouds --rig`), volume RMSE at sigma 8 / 16 mm: meshes
  /// 0.029 / 0.073 -> 0.024 / 0.045, clouds 0.036 / 0.065 -> 0.026 / 0.035; seed 2 meshes
  /// 0.036 / 0.081 -> 0.031 / 0.071, clouds 0.057 / 0.083 -> 0.050 / 0.073. Cut distance at
  /// 16 mm: clouds 5.28 -> 5.16 (seed 2 6.64 -> 5.50), meshes 3.56 -> 3.44 (seed 2 4.41 ->
  /// 4.55); sigma <= 4 within 0.11 mm.
  bool unbias_plane_points = true;
  /// Target points associated back to the posed template each round (eq. 11 with the roles
  /// swapped, then the same filter), evenly spread; 0 leaves only the template's own. The
  /// template's points find the target surface nearest them; the target's points make every
  /// part of the target pull, including ends the template falls short of. Measured on 10 lamb
  /// meshes, sigma 0 / 4 / 16 mm: cut-plane distance 3.25 / 2.61 / 5.41 -> 3.27 / 2.70 / 4.08
  /// mm, part-volume RMSE at sigma 16 0.098 -> 0.092.
  int reverse_samples = 2000;
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
  /// node, so its balance with the regularisers does not depend on num_samples. w_rot is a
  /// hundredth of part 1's: E_rot holds each node's affine to a rotation, i.e. keeps the
  /// template's proportions, while carcasses differ from it by each part's length (E_reg
  /// still keeps neighbouring nodes' affines alike). Measured on 10 lamb meshes, sigma 0 / 4 /
  /// 16 mm: cut-plane distance 3.74 / 3.40 / 5.53 -> 3.25 / 2.61 / 5.41 mm; 0.1 gave
  /// 3.61 / 3.24 / 5.42 and 0 let parts fold (avg max error 11.6 % at sigma 0).
  ///
  /// Each round's solve stops once a step gains less than 1e-4 of the cost. At 1e-7 a round
  /// took 6-11 Levenberg-Marquardt steps, all after the second gaining under 0.2 % together;
  /// the next round re-associates anyway. Measured on 10 lamb targets x sigma {0, 2, 4, 8, 16}
  /// on meshes, clouds and the rig, seeds 1 and 2: dense stage median 1.08 / 1.19 -> 0.81 /
  /// 0.72 s; per cut, distance to the true plane changed by 0.06-0.07 mm in the median, 0.25-0.33
  /// at the 90th percentile, 2.5 mm at most; each row's mean within 0.11 mm.
  EmbeddedDeformationOptions deformation{
      .w_data = 100.0,
      .w_rot = 0.01,
      .max_iterations = 20,
      .linear_solver = EmbeddedDeformationOptions::LinearSolver::kConjugateGradients,
      .function_tolerance = 1e-4};
};

struct DenseRound {
  int associated = 0;          ///< pairs found by eq. (11)
  int kept = 0;                ///< left after eq. (12)
  int reverse_associated = 0;  ///< target points paired back to the template
  int reverse_kept = 0;        ///< of those, left after eq. (12)
  /// Of the kept pairs, both ways, before the solve; template sizes.
  double mean_plane_distance = 0.0;
  SolveSummary deformation;
  double association_seconds = 0.0;
  double filter_seconds = 0.0;
};

struct DenseResult {
  bool ok = false;
  std::string error;
  io::TriangleMesh mesh;            ///< morphed template in the target's frame (template faces)
  DeformationState state;           ///< normalised template frame
  /// The target points the stage used, target frame: every stride-th (see thin_to_noise),
  /// so that what comes after (check, cut transfer) reads the cloud the way the stage did.
  Eigen::Matrix3Xd target;
  Eigen::Matrix3Xd target_normals;  ///< unit, of those points; given or estimated
  std::vector<DenseRound> rounds;
  double noise = 0.0;          ///< estimated sensor noise (standard deviation), template sizes
  int surface_neighbours = 0;  ///< target points averaged per plane point, from the noise
  int normal_passes = 0;       ///< EstimateNormals' passes, from the noise (0: own normals)
  int stride = 1;              ///< every stride-th target point was used (thin_to_noise)
  double normals_seconds = 0.0;
  double noise_seconds = 0.0;
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
