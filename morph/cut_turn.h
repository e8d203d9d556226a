#pragma once

#include <Eigen/Core>
#include <optional>

#include "geometry/triangle_mesh.h"
#include "io/annotations.h"
#include "morph/cut_line.h"

// How the morph turned and scaled the surface beside a cut. Template units.
namespace vb::morph {

/// Wahba's problem on normals: the rotation that best takes the template's vertex normals in
/// a band either side of @p cut onto the morphed template's normals at the same vertices,
/// each weighted down as it leans towards the cut's normal and left out past max_lean (the
/// cosine between them). Empty when fewer than min_vertices count, or their normals do not
/// fix a rotation (their correlation's second singular value under a tenth of its first).
std::optional<Eigen::Matrix3d> SurfaceTurn(const io::CutAnnotation& cut, const LineExtent& extent,
                                           const geometry::TriangleMesh& rest,
                                           const Eigen::Matrix3Xd& rest_normals,
                                           const Eigen::Matrix3Xd& morphed_normals, double band,
                                           double max_lean, int min_vertices);

/// How much the morph scaled the band near @p cut: the ratio of the morphed band vertices'
/// spread about their centroid to the template's.
double BandScale(const io::CutAnnotation& cut, const LineExtent& extent,
                 const geometry::TriangleMesh& rest, const geometry::TriangleMesh& morphed,
                 double band);

}  // namespace vb::morph
