#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "io/annotations.h"
#include "io/plane.h"
#include "io/plane_cut.h"
#include "io/triangle_mesh.h"

namespace vb::morph {

/// Lengths are fractions of the template's size, measured in the target's units through
/// the scale the morph found.
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
};

/// One annotated cut carried onto a target.
struct TransferredCut {
  std::string name;
  /// The cut line on the target's surface (target frame): each template line point moved
  /// by the morph, then onto the local target surface where the target was seen.
  std::vector<Eigen::Vector3d> line;
  /// Best-fit plane of the line (least squares), normal towards the part before the cut.
  io::Plane plane;
  double fit_rms = 0.0;   ///< RMS distance of the line to the plane, target units
  double coverage = 0.0;  ///< fraction of line points the target surface was seen at
  double gap = 0.0;       ///< mean distance from the morphed line to the target surface
  /// In [0, 1]: coverage, lowered as fit_rms and gap grow against their scales.
  double confidence = 0.0;
};

/// Carries the cuts of @p annotations (on @p rest, the template) onto the target through
/// @p morphed (the template morphed onto the target; same faces and vertex order).
/// @param[in] target 3 by N target points, @p target_normals unit, same size.
/// @param[in] size the template's size in target units (template size times morph scale).
std::vector<TransferredCut> TransferCuts(const io::Annotations& annotations,
                                         const io::TriangleMesh& rest,
                                         const io::TriangleMesh& morphed,
                                         const Eigen::Matrix3Xd& target,
                                         const Eigen::Matrix3Xd& target_normals, double size,
                                         const CutTransferOptions& options = {});

/// Virtual cutting: the parts of @p mesh (the target, or the morphed template standing in
/// for it) between the transferred planes, in the annotations' part order.
std::vector<io::PartMeasure> CutParts(const io::TriangleMesh& mesh,
                                      const std::vector<TransferredCut>& cuts);

}  // namespace vb::morph
