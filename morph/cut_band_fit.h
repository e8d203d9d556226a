#pragma once

#include <Eigen/Core>
#include <optional>

#include "geometry/triangle_mesh.h"
#include "io/annotations.h"
#include "morph/cut_line.h"

// Where along its normal a cut sits, read from the template's band either side of it
// registered to the target's plane points there.
namespace vb::morph {

/// A band's reading, template units.
struct BandSlide {
  double along = 0.0;  ///< where the cut sits along its normal from the line's centroid
  double error = 0.0;  ///< its standard error
};

/// Registers the template's band either side of @p cut to the target's plane points there,
/// in the template's frame: each point p is mapped back through the morph's local turn and
/// scale about the line's centroids (rest @p extent.centre, target @p target_centre), then
/// matched to the nearest template band vertex, point to plane, under the model
///   p~ = c + (k u - delta) n + h w + a e1 + b e2 + t1 e1 x (p - c) + t2 e2 x (p - c),
///   u = n.(p - c),  w = (p - c) - u n,
/// with n the cut's normal and e1, e2 across it: a shift delta along the cut, stretches k
/// along it and h across it (priors N(1, stretch_sigma^2)), a sideways shift and a small
/// tilt about either axis across the cut (priors N(0, tilt_sigma^2)). Linear in the
/// unknowns, so each round is a 7 by 7 solve; pairs beyond 3 median residuals are left
/// out. While the pairs are chosen the shift has the prior N(0, slide_sigma^2) (the morph's
/// placement), so a band that says little does not wander; the reading returned is what the
/// chosen pairs say without it, for TransferCuts to weigh against the other cuts'.
/// Neighbouring plane points share target points, so their residuals are not independent:
/// the residual variance is counted @p shared times, for the priors and the error. A plane
/// point paired with band vertex v is taken to lie @p outward(v) inside the surface (empty:
/// nowhere). Returns where the cut (u~ = 0) lies, u = delta / k, and its standard error, both
/// in template units; empty when too few points take part, the fit leaves its bounds or the
/// band fixes no shift.
std::optional<BandSlide> FitBandSlide(
    const io::CutAnnotation& cut, const LineExtent& extent, const geometry::TriangleMesh& rest,
    const Eigen::Matrix3Xd& rest_normals, const Eigen::Matrix3d& turn, double scale,
    const Eigen::Vector3d& target_centre, const Eigen::Matrix3Xd& plane_points, double band,
    double margin, double stretch_sigma, double slide_sigma, double tilt_sigma, int shared,
    const Eigen::VectorXd& outward);

}  // namespace vb::morph
