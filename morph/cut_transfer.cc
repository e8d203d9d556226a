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
  // Per cut, the turn of its surface band when a band fit follows (else none).
  std::vector<std::optional<Eigen::Matrix3d>> band_turns;
  const double band = slide_band * template_size;
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
    std::optional<Eigen::Matrix3d> band_turn;
    if (t.line.size() >= 3) {
      t.plane = FitPlane(t.line);
      double sum = 0.0;
      for (const Eigen::Vector3d& p : t.line) sum += std::pow(t.plane.SignedDistance(p), 2);
      t.fit_rms = std::sqrt(sum / static_cast<double>(t.line.size()));
      if (options.normal_band > 0) {
        if (const std::optional<Eigen::Matrix3d> turn =
                SurfaceTurn(cut, reading.extent, rest, rest_normals, morphed_normals,
                            options.normal_band * template_size, options.normal_max_lean,
                            options.min_band_vertices)) {
          t.plane.normal = (*turn * cut.plane.normal).normalized();
          t.oriented_by_normals = true;
          if (slide_band > 0) {
            reading.scale = BandScale(cut, reading.extent, rest, morphed, band);
            if (reading.scale > 0) band_turn = turn;
          }
        }
      }
    }
    out.push_back(std::move(t));
    readings.push_back(std::move(reading));
    band_turns.push_back(band_turn);
  }

  // The band fits read plane points in their bands only; those are made for the target points
  // that can reach a band: a plane point lies within twice the plane radius of its point (the
  // centroid within one radius, the curvature correction at most one more).
  const double plane_radius = options.slide_plane_radius * size;
  std::vector<int> near_a_band;
  for (Eigen::Index j = 0; j < target.cols(); ++j) {
    for (std::size_t c = 0; c < out.size(); ++c) {
      if (!band_turns[c]) continue;
      const CutReading& reading = readings[c];
      const Eigen::Vector3d from_centre = target.col(j) - out[c].plane.point;
      const Eigen::Vector3d p =
          reading.extent.centre + band_turns[c]->transpose() * from_centre / reading.scale;
      const double reach = 2.0 * plane_radius / reading.scale * (1.0 + 1e-6);
      if (NearTheCut(annotations.cuts[c], reading.extent, p, band + reach)) {
        near_a_band.push_back(static_cast<int>(j));
        break;
      }
    }
  }
  const Eigen::Matrix3Xd plane_points =
      near_a_band.empty() ? Eigen::Matrix3Xd()
                          : PlanePointsOf(target, target_normals, index, plane_neighbours,
                                          plane_radius, true, near_a_band, pool);
  // The cuts' band fits are independent: each on one of the pool's threads, each writing only
  // its own cut's entries.
  ForEach(pool, static_cast<int>(out.size()), [&](int index_of_cut) {
    const auto c = static_cast<std::size_t>(index_of_cut);
    if (!band_turns[c]) return;
    TransferredCut& t = out[c];
    CutReading& reading = readings[c];
    reading.band = FitBandSlide(annotations.cuts[c], reading.extent, rest, rest_normals,
                                *band_turns[c], reading.scale, t.plane.point, plane_points, band,
                                options.slide_margin * template_size, options.slide_stretch_sigma,
                                options.slide_sigma * template_size, options.slide_tilt_sigma,
                                options.slide_plane_neighbours, outward);
    if (reading.band) {
      t.band_slide = reading.scale * reading.band->along;
      t.band_slide_error = reading.scale * reading.band->error;
    }
  });

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
