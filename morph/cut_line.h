#pragma once

#include <Eigen/Core>
#include <vector>

#include "geometry/plane.h"
#include "geometry/triangle_mesh.h"
#include "io/annotations.h"
#include "morph/point_index.h"

// The cut line carried by the morph: where it lies on the template, the line on the target,
// and which side of it is which. Template units unless said.
namespace vb::morph {

/// Least-squares plane of @p points: centroid and direction of least spread.
geometry::Plane FitPlane(const std::vector<Eigen::Vector3d>& points);

/// Where a cut line lies on the template: its centroid and the largest distance from it.
struct LineExtent {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

/// The extent of @p cut's line on @p rest.
LineExtent ExtentOf(const io::CutAnnotation& cut, const geometry::TriangleMesh& rest);

/// Template vertices within @p band of the cut's plane and close to its line, so that other
/// limbs crossing the plane do not count.
bool NearTheCut(const io::CutAnnotation& cut, const LineExtent& extent,
                const Eigen::Vector3d& vertex, double band);

/// Which way the part before the cut lies on the morphed mesh: from the template vertices in
/// a band on the far side of the cut to those in the band on its near side.
Eigen::Vector3d TowardsPartBefore(const io::CutAnnotation& cut, const LineExtent& extent,
                                  const geometry::TriangleMesh& rest,
                                  const geometry::TriangleMesh& morphed, double band);

/// A template cut line on the target.
struct LineOnTarget {
  std::vector<Eigen::Vector3d> points;  ///< target frame
  double coverage = 0.0;  ///< fraction of the points where the target surface was seen
  double gap = 0.0;       ///< mean distance from the morphed line to the target surface
};

/// Each point of @p cut's line moved by the morph (@p morphed, same faces as the template),
/// then along the target's normal onto the mean of its @p neighbours nearest target points
/// within @p radius (target units); where none lie that close, the morphed point stands in
/// for the unseen target.
/// @param[in] target, target_normals 3 by N (unit normals); @p index over @p target.
LineOnTarget CarryLine(const io::CutAnnotation& cut, const geometry::TriangleMesh& morphed,
                       const Eigen::Matrix3Xd& target, const Eigen::Matrix3Xd& target_normals,
                       const PointIndex& index, int neighbours, double radius);

}  // namespace vb::morph
