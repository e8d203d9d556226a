#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

#include "geometry/plane_cut.h"
#include "geometry/triangle_mesh.h"
#include "morph/cut_transfer.h"

// Virtual cutting: the parts between transferred cuts and their volumes.
namespace vb::morph {

/// Virtual cutting: the parts of @p mesh (the target, or the morphed template standing in
/// for it) between the transferred planes, in the annotations' part order.
std::vector<geometry::PartMeasure> CutParts(const geometry::TriangleMesh& mesh,
                                            const std::vector<TransferredCut>& cuts);

struct PartVolumeOptions {
  /// Target points farther than this from the morphed surface (a fraction of the template's
  /// size) are taken as not of it.
  double max_offset = 0.03;
  /// Fewer target points than this in a part leave its volume as the morph has it.
  int min_points = 50;
};

/// Virtual cutting of the morphed template, with each part's volume then told by the target:
/// the morph's part volume plus its outer area times the mean signed distance (outward
/// positive) from the target points in the part to the morphed surface. Where the morph
/// stayed fatter or thinner than the carcass (its regularisers resist a change of girth, and
/// more so on noisy targets, whose data term is weighted down), the target points lie inside
/// or outside it by about that much all over the part; their mean averages the sensor noise
/// away. The area is the morph's.
/// @param[in] morphed the morphed template, target frame (its vertex normals computed when
/// it has none).
/// @param[in] target 3 by N target points, same frame; @p size as TransferCuts'.
/// @param nearest_vertex for each target point, the morphed mesh's nearest vertex
///   (NearestEach), or empty to find them here.
std::vector<geometry::PartMeasure> CutTargetParts(const geometry::TriangleMesh& morphed,
                                                  const std::vector<TransferredCut>& cuts,
                                                  const Eigen::Matrix3Xd& target, double size,
                                                  const PartVolumeOptions& options = {},
                                                  std::span<const int> nearest_vertex = {});

}  // namespace vb::morph
