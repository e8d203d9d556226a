#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "geometry/plane.h"
#include "geometry/triangle_mesh.h"
#include "io/annotations.h"
#include "morph/worker_pool.h"

namespace vb::morph {

/// How cuts are carried onto a target (docs/method.md, "After the morph"). Lengths are
/// fractions of the template's size, measured in the target's units through the scale the
/// morph found; noise levels likewise. The measurements behind the defaults are in
/// docs/decisions.md.
struct CutTransferOptions {
  /// A cut-line point counts as seen on the target when target points lie this close.
  double support_radius = 0.02;
  /// Target points averaged (within support_radius) to place a line point on the surface.
  int surface_neighbours = 10;
  /// Plane-fit RMS at which confidence halves: a band saw cuts straight, so a transferred
  /// line that is not planar means the morph bent the region.
  double fit_scale = 0.004;
  /// Mean morph-to-target gap along the line at which confidence halves.
  double gap_scale = 0.01;
  /// Width of the band beside a cut used to tell which side is which, for the normal.
  double side_band = 0.05;
  /// Half-width of the band either side of a cut whose surface normals orient the plane
  /// (see TransferredCut::plane); 0 orients it by the line's own plane fit alone.
  double normal_band = 0.02;
  /// Band normals count less as they lean towards the cut's normal, and not at all past
  /// this cosine with it: there the body tapers, and a stretch along it turns them.
  double normal_max_lean = 0.3;
  /// Band vertices (within normal_max_lean) needed before their normals are used.
  int min_band_vertices = 20;
  /// Half-width of the band either side of a cut that is registered to the target to place
  /// the plane along its normal (see TransferredCut::slide); 0 leaves the plane at the
  /// line's centroid. Needs the normals' turn (normal_band > 0).
  double slide_band = 0.04;
  /// On targets noisier than this (TransferCuts' noise, a fraction of the template's size)
  /// the band widens by sqrt(noise / slide_band_noise): through noise only a longer stretch
  /// of the profile says where the cut is, while a wide band on a clean target takes in
  /// joints a single turned and stretched piece does not model.
  double slide_band_noise = 0.0035;
  /// Template vertices this far beyond slide_band are matched too, so a shifted band still
  /// finds its template surface.
  double slide_margin = 0.03;
  /// Prior standard deviation of the band's stretch along and across the cut (relative):
  /// parts of a carcass differ from the template's by several percent, rarely by tens.
  double slide_stretch_sigma = 0.1;
  /// Prior standard deviation (radians) of the band's tilt about the axes across the cut,
  /// beyond the normals' turn. The turn is read from the normals within normal_band of the
  /// cut; where the carcass bends within the wider slide band, an untilted piece could only
  /// match it by a shift, which would read as the cut being elsewhere.
  double slide_tilt_sigma = 0.15;
  /// Prior standard deviation of the morph's slide along the body at a cut (fraction of the
  /// template's size): what the morph's own placement is good to (about 4 mm on a lamb).
  double slide_sigma = 0.0035;
  /// The slides at two cuts correlate as exp(-(d / slide_correlation_length)^2) times the
  /// cosine between their planes' normals, d being the distance between the lines' centroids
  /// on the template (fraction of its size): a morph that placed a part too far along the
  /// body moved the cuts either side of it together. Each cut's placement is then read from
  /// every band fit, each counted by its error (a Gaussian-process posterior), so a band
  /// whose profile says little (the loin / rack cut along the ribs) borrows from a near one
  /// that says more. 0 treats cuts apart.
  double slide_correlation_length = 0.2;
  /// What a band fit's reading is good to at best, beyond its own standard error (fraction
  /// of the size): it models a cut's neighbourhood as one turned and stretched piece.
  double slide_model_error = 0.00125;
  /// The band fit uses plane points (plane_points.h) of this many target points within
  /// slide_plane_radius, so sensor noise averages out before the fit.
  int slide_plane_neighbours = 20;
  double slide_plane_radius = 0.03;
  /// On targets noisier than slide_band_noise the plane points average more target points,
  /// slide_plane_neighbours x (noise / slide_band_noise)^2, up to this many, as the dense
  /// stage's do (DenseOptions::max_surface_neighbours). The fit's residuals still count one
  /// in slide_plane_neighbours as independent.
  int max_slide_plane_neighbours = 64;
  /// Each plane point is taken as lying sigma^2 (k1 + k2) inside the surface, sigma the
  /// target's noise and k1 + k2 the template's curvature sum at the paired vertex (at most
  /// sigma), as in DenseOptions::unbias_plane_points: a centroid on a noisy convex surface
  /// sits that far in.
  bool unbias_plane_points = true;
};

/// One annotated cut carried onto a target.
struct TransferredCut {
  std::string name;
  /// The cut line on the target's surface (target frame): each template line point moved
  /// by the morph, then onto the local target surface where the target was seen.
  std::vector<Eigen::Vector3d> line;
  /// The cutting plane, normal towards the part before the cut. It passes through the
  /// line's centroid. Its normal is the expert's plane normal turned as the morph turned the
  /// surface beside the cut: the rotation that best takes the template's vertex normals in
  /// a band either side of the cut (those the saw meets nearly square on) onto the morphed
  /// template's normals there. Where the surface does not say where along it a vertex
  /// belongs (along a tube), the morph can slip the line and tilt the line's own plane fit;
  /// the normals there do not change with the slip. Where the band holds too few vertices
  /// or their normals fix no rotation (a flat patch), the normal is the line's
  /// least-squares one.
  geometry::Plane plane;
  /// True when plane.normal came from the band's normals, false from the line's plane fit.
  bool oriented_by_normals = false;
  /// How far the plane was moved along its normal from the line's centroid (target units,
  /// towards the part before the cut when positive in the expert's normal's sense): the
  /// template's own band either side of the cut, registered to the target's there (its
  /// place along the cut's normal, stretch along and across it and sideways shift), says
  /// where the cut sits where the morph slid along a body that changes its profile slowly.
  /// It is the posterior of every cut's band reading under the prior of
  /// CutTransferOptions::slide_sigma and slide_correlation_length, so a cut whose own band
  /// says little moves with a near one that says more. 0 when not moved (no normals' turn,
  /// or no band fit anywhere).
  double slide = 0.0;
  /// Standard deviation of that placement, target units (0 when not moved); about the
  /// prior's (CutTransferOptions::slide_sigma) where no band says much.
  double slide_error = 0.0;
  /// This cut's own band reading and its standard error, target units, before the prior
  /// and the other cuts were heard (0 when the fit was not made or left its bounds).
  double band_slide = 0.0;
  double band_slide_error = 0.0;
  /// Half-width of the band that placement was fitted on, target units (0 when none was):
  /// CutTransferOptions::slide_band, widened on noisy targets.
  double slide_band = 0.0;
  /// RMS distance of the line to its own least-squares plane (how far from straight the
  /// morph bent it), target units.
  double fit_rms = 0.0;
  double coverage = 0.0;  ///< fraction of line points the target surface was seen at
  double gap = 0.0;       ///< mean distance from the morphed line to the target surface
  /// In [0, 1]: coverage, lowered as fit_rms and gap grow against their scales.
  double confidence = 0.0;
};

/// Carries the cuts of @p annotations (on @p rest, the template) onto the target through
/// @p morphed (the template morphed onto the target; same faces and vertex order).
/// @param[in] target 3 by N target points, @p target_normals unit, same size.
/// @param[in] size the template's size in target units (template size times morph scale).
/// @param[in] noise the target's sensor noise (standard deviation along the surface), a
/// fraction of the template's size, as DenseResult::noise; 0 when clean or unknown.
/// @param pool when given, the target's plane points are made on its threads; the result is
///   the same on any number of threads.
std::vector<TransferredCut> TransferCuts(const io::Annotations& annotations,
                                         const geometry::TriangleMesh& rest,
                                         const geometry::TriangleMesh& morphed,
                                         const Eigen::Matrix3Xd& target,
                                         const Eigen::Matrix3Xd& target_normals, double size,
                                         const CutTransferOptions& options = {},
                                         double noise = 0.0, WorkerPool* pool = nullptr);

}  // namespace vb::morph
