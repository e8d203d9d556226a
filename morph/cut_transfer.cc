#include "morph/cut_transfer.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "geometry/mesh_measures.h"
#include "io/error.h"
#include "morph/cut_band_fit.h"
#include "morph/cut_line.h"
#include "morph/cut_placement.h"
#include "morph/cut_turn.h"
#include "morph/plane_points.h"
#include "morph/point_index.h"

namespace vb::morph {

std::vector<TransferredCut> TransferCuts(const io::Annotations& annotations,
                                         const geometry::TriangleMesh& rest,
                                         const geometry::TriangleMesh& morphed,
                                         const Eigen::Matrix3Xd& target,
                                         const Eigen::Matrix3Xd& target_normals, double size,
                                         const CutTransferOptions& options, double noise,
                                         WorkerPool* pool) {
  VB_DEMAND(rest.num_vertices() == morphed.num_vertices() && target.cols() > 0 &&
            target_normals.cols() == target.cols() && size > 0 && noise >= 0 &&
            options.slide_band_noise > 0 && options.slide_sigma > 0 &&
            options.slide_correlation_length >= 0 && options.slide_model_error >= 0);
  const double template_size = geometry::BoundingBoxDiagonal(rest.V);
  const double relative_noise = noise / options.slide_band_noise;
  const double slide_band = options.slide_band * std::sqrt(std::max(1.0, relative_noise));
  // Noisier targets average more points per plane point (see max_slide_plane_neighbours).
  const int plane_neighbours = NeighboursForNoise(
      options.slide_plane_neighbours, options.max_slide_plane_neighbours, relative_noise);
  const PointIndex index(target);
  const double radius = options.support_radius * size;
  Eigen::Matrix3Xd computed_rest_normals, computed_morphed_normals;  // for meshes without
  const Eigen::Matrix3Xd& rest_normals =
      rest.has_normals() ? rest.N : (computed_rest_normals = geometry::VertexNormals(rest));
  const Eigen::Matrix3Xd& morphed_normals =
      morphed.has_normals() ? morphed.N
                            : (computed_morphed_normals = geometry::VertexNormals(morphed));
  Eigen::Matrix3Xd plane_points;  // of the target, made when the first band fit needs them
  // How far out along the normal a noisy target's plane point paired with each template
  // vertex is moved, template units (see unbias_plane_points); empty on a clean target.
  Eigen::VectorXd outward;
  if (options.unbias_plane_points && noise > 0) {
    const double sigma = noise * template_size;
    outward = geometry::CurvatureSums(rest, rest_normals).unaryExpr([sigma](double curvature) {
      return CurvatureOffset(curvature, sigma);
    });
  }
  std::vector<TransferredCut> out;
  std::vector<CutReading> readings;
  for (const io::CutAnnotation& cut : annotations.cuts) {
    TransferredCut t;
    CutReading reading;
    t.name = cut.name;
    reading.extent = ExtentOf(cut, rest);
    LineOnTarget carried =
        CarryLine(cut, morphed, target, target_normals, index, options.surface_neighbours, radius);
    t.line = std::move(carried.points);
    t.coverage = carried.coverage;
    t.gap = carried.gap;
    if (t.line.size() >= 3) {
      const LineExtent& extent = reading.extent;
      t.plane = FitPlane(t.line);
      double sum = 0.0;
      for (const Eigen::Vector3d& p : t.line) sum += std::pow(t.plane.SignedDistance(p), 2);
      t.fit_rms = std::sqrt(sum / static_cast<double>(t.line.size()));
      if (options.normal_band > 0) {
        if (const std::optional<Eigen::Matrix3d> turn =
                SurfaceTurn(cut, extent, rest, rest_normals, morphed_normals,
                            options.normal_band * template_size, options.normal_max_lean,
                            options.min_band_vertices)) {
          t.plane.normal = (*turn * cut.plane.normal).normalized();
          t.oriented_by_normals = true;
          if (slide_band > 0) {
            const double band = slide_band * template_size;
            reading.scale = BandScale(cut, extent, rest, morphed, band);
            if (plane_points.cols() == 0) {
              plane_points = PlanePoints(target, target_normals, index, plane_neighbours,
                                         options.slide_plane_radius * size, true, pool);
            }
            if (reading.scale > 0) {
              reading.band =
                  FitBandSlide(cut, extent, rest, rest_normals, *turn, reading.scale, t.plane.point,
                               plane_points, band, options.slide_margin * template_size,
                               options.slide_stretch_sigma, options.slide_sigma * template_size,
                               options.slide_tilt_sigma, options.slide_plane_neighbours, outward);
            }
            if (reading.band) {
              t.band_slide = reading.scale * reading.band->along;
              t.band_slide_error = reading.scale * reading.band->error;
            }
          }
        }
      }
    }
    out.push_back(std::move(t));
    readings.push_back(std::move(reading));
  }

  Eigen::VectorXd slide, slide_deviation;
  const bool any_band =
      PlaceTogether(annotations, readings, options.slide_sigma * template_size,
                    options.slide_correlation_length * template_size,
                    options.slide_model_error * template_size, &slide, &slide_deviation);
  for (std::size_t c = 0; c < out.size(); ++c) {
    TransferredCut& t = out[c];
    if (t.line.size() < 3) continue;
    const io::CutAnnotation& cut = annotations.cuts[c];
    const CutReading& reading = readings[c];
    if (any_band && reading.scale > 0) {
      const Eigen::Index i = static_cast<Eigen::Index>(c);
      t.slide = reading.scale * slide(i);
      t.slide_error = reading.scale * slide_deviation(i);
      t.slide_band = slide_band * size;
      t.plane.point += t.slide * t.plane.normal;
    }
    const Eigen::Vector3d towards =
        TowardsPartBefore(cut, reading.extent, rest, morphed, options.side_band * template_size);
    if (towards.dot(t.plane.normal) < 0) t.plane.normal = -t.plane.normal;
    const double fit = t.fit_rms / (options.fit_scale * size);
    const double gap = t.gap / (options.gap_scale * size);
    t.confidence = t.coverage / (1.0 + fit * fit) / (1.0 + gap * gap);
  }
  return out;
}

}  // namespace vb::morph
