#pragma once

#include <Eigen/Core>
#include <numbers>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "morph/association_filter.h"
#include "morph/coarse_alignment.h"
#include "morph/dense_association.h"
#include "morph/embedded_deformation.h"
#include "morph/template_model.h"

namespace vb::morph {

/// Section II-B (docs/method.md, "Dense surface alignment"). Lengths are fractions of the
/// template's size (its normalised frame); noise levels likewise. The measurements behind the
/// defaults are in docs/decisions.md.
struct DenseOptions {
  /// Template vertices associated per round (every n-th vertex; all when the mesh is smaller).
  int num_samples = 2000;
  /// A target given without normals gets principal-axis normals. Noisy ones
  /// (EstimateNormals' passes) average about normal_neighbours x (noise / surface_noise)^2
  /// points, at most max_normal_passes times normal_neighbours: a tilted plane has a part
  /// along the surface, so noisy normals would slide the template.
  int normal_neighbours = 24;
  int max_normal_passes = 8;
  /// Where the noise leaves one pass (under about 1.2 surface_noise), each normal is fitted
  /// first to its min_normal_neighbours nearest, then again (RefitNormals) to the points
  /// within a radius of its own: normal_reach noise levels, and no shorter than where
  /// normal_neighbours points lie at the cloud's median density, but no farther than
  /// normal_curvature_reach radii of curvature of the posed template at the nearest vertex
  /// (1 / |k1 + k2|), so that a thin limb's normals do not reach round it; at most
  /// max_normal_neighbours points. A radius held under where min_normal_neighbours points lie
  /// keeps the first fit; a sparser patch (a hole's rim) may fit fewer points, 3 at least.
  /// normal_reach 0: the noise does not widen them; min_normal_neighbours equal to
  /// normal_neighbours: each point's normal_neighbours nearest where the shape allows no
  /// more. A target's own normals (a mesh's faces) are used as given, all turned when most
  /// point against the posed template's (DenseResult::turned_normals).
  int min_normal_neighbours = 12;
  double normal_reach = 4.0;
  double normal_curvature_reach = 0.5;
  int max_normal_neighbours = 500;
  /// Whether estimated normals lean on the posed template's: the planes of eq. (14) and the
  /// tangent reach above face (1 - w) n + w t, n the estimate, t the normal of the posed
  /// template's nearest vertex as the previous round left it, w = r^2 / (1 + r^2), r = noise /
  /// noise_reference (DenseResult::normal_prior_weight); the plane points are corrected along
  /// the first round's blend. Eq. (11) pairs on the estimates. Given normals are used as given.
  /// An estimate whose cosine to t is below normal_prior_min_cosine is used as estimated:
  /// turned more than 45 degrees (1/sqrt(2)), the normal lies more along the template's
  /// surface than across it, so the template is not on that surface, and its planes must not
  /// draw it over the points there (the whole-morph check, which reads the cloud's coverage,
  /// would then pass a part put elsewhere; decisions.md, "Noisy normals lean on the
  /// template's where they roughly agree"). A cosine; 0 lets every estimate lean, above 1 none
  /// (the morph is then the one without the prior).
  bool normal_prior = true;
  double normal_prior_min_cosine = std::numbers::sqrt2 / 2.0;
  /// Each associated target point is replaced by a plane point (PlanePoints): the centroid
  /// of this many nearest target points, which averages sensor noise along the normal. Few,
  /// so curved limbs are not flattened. This is the count for targets no noisier than
  /// surface_noise.
  int surface_neighbours = 10;
  /// Noisier targets average more points, surface_neighbours x (noise / surface_noise)^2
  /// (NeighboursForNoise), so that their plane points keep the noise of a target at
  /// surface_noise, up to max_surface_neighbours (past that, limbs flatten).
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
  /// nearest neighbours reached under about 4 sigma; NoiseEstimate::stride) is used at every
  /// n-th point, here and in the check and cut transfer after (DenseResult::target), so that
  /// the neighbourhoods of the normals and plane points, counted in points, reach beyond the
  /// noise as they do on a sparser cloud.
  bool thin_to_noise = true;
  /// Noise level at which the data weight halves: the data term is weighted by
  /// 1 / (1 + (noise / noise_reference)^2), a maximum-likelihood weighting.
  double noise_reference = 0.0026;
  /// Each plane point is moved along the normal by the mean offset of its neighbours' points
  /// from their own centroids: a centroid lies inside a convex surface by about the curvature
  /// times the neighbourhood's squared radius, and on a tapered body the template would
  /// answer that inward pull by sliding along the taper.
  bool correct_plane_offset = true;
  /// Each plane point is moved out along its normal by sigma^2 times the posed template's
  /// curvature sum (k1 + k2) at the paired vertex, at most sigma (CurvatureOffset; sigma the
  /// estimated noise): how far a ball's centroid sits towards the concave side of a noisy
  /// surface, which correct_plane_offset removes only in part. Without it the morph shrinks
  /// as the noise grows.
  bool unbias_plane_points = true;
  /// Target points associated back to the posed template each round (eq. 11 with the roles
  /// swapped), evenly spread; of those paired to one vertex, the nearest is kept; 0 leaves
  /// only the template's own. The target's points make every part of the target pull,
  /// including ends the template falls short of.
  int reverse_samples = 2000;
  /// A template vertex's pair is dropped when the vertex lies farther along its target
  /// point's plane than this many plane-point radii from the point. A radius is
  /// sqrt(k / (pi density)): k the points a plane point averages (DenseResult::
  /// surface_neighbours, which grows with the noise), density that of the target points as
  /// used (NoiseEstimate::density, template sizes, every stride-th point); surface_radius,
  /// which caps the patch on sparse clouds, does not enter. So far out the plane is
  /// extrapolated over what the target does not show: a vertex over a camera shadow or a hole
  /// pairs with a point on its rim, whose plane would pull it flat across. The target's own
  /// pairs (reverse_samples) are not limited so. 0: off.
  double max_tangent_reach = 3.0;
  DenseAssociationOptions association;
  AssociationFilterOptions filter;
  /// Rounds of association -> filtering -> deformation, each from the previous result.
  int rounds = 5;
  /// w_rot and w_reg are multiplied by this each round: a stiff start that cannot fold, then
  /// freedom to follow the surface's own features.
  double stiffness_decay = 0.6;
  /// E_reg measures each residual from the coarse pose's residual shortened by this times
  /// the edge's rest length (KeptBends; residual over edge about the turn in radians): a limb
  /// the posture fit turned at a joint is not pulled back where the data weigh little (a
  /// noisy cloud), while the fit's small distortions still relax. A large value keeps none.
  double free_bend = 0.3;
  /// Eq. (13). w_data is per graph node: it is divided by the number of associations per
  /// node, so its balance with the regularisers does not depend on num_samples, and
  /// multiplied by the noise weighting above. w_rot is a hundredth of the coarse stage's:
  /// E_rot holds each node's affine to a rotation, i.e. keeps the template's proportions,
  /// while carcasses differ from it by each part's length (E_reg still keeps neighbouring
  /// nodes' affines alike). Each round's solve stops once a step gains less than 1e-4
  /// of the cost: the next round re-associates anyway.
  EmbeddedDeformationOptions deformation{.w_data = 100.0,
                                         .w_rot = 0.01,
                                         .max_iterations = 20,
                                         .function_tolerance = 1e-4,
                                         .deadline = {}};
};

struct DenseRound {
  int associated = 0;          ///< pairs found by eq. (11)
  int kept = 0;                ///< left after eq. (12)
  int reverse_associated = 0;  ///< target points paired back to the template
  int reverse_kept = 0;        ///< of those, the nearest to each vertex paired
  /// Of the template's pairs kept by eq. (12), those then dropped as too far along the
  /// target's plane (DenseOptions::max_tangent_reach): kept - beyond_reach make constraints.
  int beyond_reach = 0;
  /// Of the kept pairs, both ways, before the solve; template sizes.
  double mean_plane_distance = 0.0;
  SolveSummary deformation;
  /// Eq. (11) and eq. (12), both ways, summed over the threads that ran them (more than
  /// the wall time when the two ways ran at once).
  double association_seconds = 0.0;
  double filter_seconds = 0.0;
};

struct DenseResult {
  bool ok = false;
  std::string error;
  geometry::TriangleMesh mesh;  ///< morphed template in the target's frame (template faces)
  DeformationState state;       ///< normalised template frame
  /// The target points the stage used, target frame: every stride-th (see thin_to_noise),
  /// so that what comes after (check, cut transfer) reads the cloud the way the stage did.
  Eigen::Matrix3Xd target;
  /// Unit, of those points: given, or estimated and blended as the last round's planes faced
  /// (DenseOptions::normal_prior).
  Eigen::Matrix3Xd target_normals;
  std::vector<DenseRound> rounds;
  double noise = 0.0;    ///< estimated sensor noise (standard deviation), template sizes
  double noise_m = 0.0;  ///< the same in the target's units (metres): noise x the morph's scale
  /// Target points per square metre (target units), as the stage used them (every
  /// stride-th): NoiseEstimate::density over the morph's scale squared.
  double density_m2 = 0.0;
  int surface_neighbours = 0;  ///< target points averaged per plane point, from the noise
  int normal_passes = 0;       ///< EstimateNormals' passes, from the noise (0: own normals)
  int widened_normals = 0;     ///< normals given a radius of their own (one pass, RefitNormals)
  /// Weight w in [0, 1) of the posed template's normal in each plane's (DenseOptions::
  /// normal_prior), unitless; 0 when the target's normals were given or the prior is off.
  double normal_prior_weight = 0.0;
  /// The target's own normals were turned: most pointed against the posed template's.
  bool turned_normals = false;
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
/// @param pool when given, each round's two association ways share its threads; the result
///   is the same on any number of threads.
DenseResult AlignDense(const TemplateModel& model, const CoarseResult& coarse,
                       const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& target_normals,
                       const DenseOptions& options = {}, WorkerPool* pool = nullptr);

}  // namespace vb::morph
