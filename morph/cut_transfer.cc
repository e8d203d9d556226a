#include "morph/cut_transfer.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "io/error.h"
#include "io/mesh_measures.h"
#include "io/mesh_topology.h"
#include "io/surface_point.h"
#include "morph/dense_association.h"
#include "morph/feature_association.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

// Least-squares plane of @p points: centroid and direction of least spread.
io::Plane FitPlane(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) scatter += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
  return io::Plane{.point = mean, .normal = solver.eigenvectors().col(0).normalized()};
}

// Where a cut line lies on the template: its centroid and the largest distance from it.
struct LineExtent {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

LineExtent ExtentOf(const io::CutAnnotation& cut, const io::TriangleMesh& rest) {
  LineExtent e;
  for (const io::SurfacePoint& p : cut.line) e.centre += io::Evaluate(rest, p);
  e.centre /= static_cast<double>(cut.line.size());
  for (const io::SurfacePoint& p : cut.line)
    e.radius = std::max(e.radius, (io::Evaluate(rest, p) - e.centre).norm());
  return e;
}

// Template vertices within @p band of the cut's plane and close to its line, so that other
// limbs crossing the plane do not count.
bool NearTheCut(const io::CutAnnotation& cut, const LineExtent& extent,
                const Eigen::Vector3d& vertex, double band) {
  return (vertex - extent.centre).norm() <= extent.radius + band &&
         std::abs(cut.plane.SignedDistance(vertex)) <= band;
}

// Which way the part before the cut lies on the morphed mesh: from the template vertices in
// a band on the far side of the cut to those in the band on its near side.
Eigen::Vector3d TowardsPartBefore(const io::CutAnnotation& cut, const LineExtent& extent,
                                  const io::TriangleMesh& rest, const io::TriangleMesh& morphed,
                                  double band) {
  Eigen::Vector3d before = Eigen::Vector3d::Zero(), after = Eigen::Vector3d::Zero();
  int n_before = 0, n_after = 0;
  for (int v = 0; v < rest.num_vertices(); ++v) {
    if (!NearTheCut(cut, extent, rest.V.col(v), band)) continue;
    if (cut.plane.SignedDistance(rest.V.col(v)) > 0) {
      before += morphed.V.col(v);
      ++n_before;
    } else {
      after += morphed.V.col(v);
      ++n_after;
    }
  }
  if (n_before == 0 || n_after == 0) return Eigen::Vector3d::Zero();
  return before / n_before - after / n_after;
}

// A rotation is fixed by normals only when they spread in two directions: the second
// singular value of their correlation must be at least this fraction of the first.
constexpr double kMinNormalSpread = 0.1;

// Wahba's problem on normals: the rotation that best takes the template's vertex normals in
// a band either side of @p cut onto the morphed template's normals at the same vertices,
// each weighted down as it leans towards the cut's normal and left out past max_lean (the
// cosine between them). Empty when fewer than min_vertices count, or their normals do not
// fix a rotation.
std::optional<Eigen::Matrix3d> SurfaceTurn(const io::CutAnnotation& cut, const LineExtent& extent,
                                           const io::TriangleMesh& rest,
                                           const Eigen::Matrix3Xd& rest_normals,
                                           const Eigen::Matrix3Xd& morphed_normals, double band,
                                           double max_lean, int min_vertices) {
  Eigen::Matrix3d correlation = Eigen::Matrix3d::Zero();
  int used = 0;
  for (int v = 0; v < rest.num_vertices(); ++v) {
    if (!NearTheCut(cut, extent, rest.V.col(v), band)) continue;
    // Normals leaning towards the cut's own normal belong to where the surface tapers; a
    // stretch along the body turns those, not the ones the saw meets square on.
    const double lean = rest_normals.col(v).dot(cut.plane.normal) / max_lean;
    if (std::abs(lean) >= 1.0) continue;
    correlation += (1.0 - lean * lean) * morphed_normals.col(v) * rest_normals.col(v).transpose();
    ++used;
  }
  if (used < min_vertices) return std::nullopt;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(correlation,
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  if (svd.singularValues()(1) < kMinNormalSpread * svd.singularValues()(0)) return std::nullopt;
  return NearestRotation(svd);
}

// How much the morph scaled the band near @p cut: the ratio of the morphed band vertices'
// spread about their centroid to the template's.
double BandScale(const io::CutAnnotation& cut, const LineExtent& extent,
                 const io::TriangleMesh& rest, const io::TriangleMesh& morphed, double band) {
  std::vector<int> in_band;
  for (int v = 0; v < rest.num_vertices(); ++v)
    if (NearTheCut(cut, extent, rest.V.col(v), band)) in_band.push_back(v);
  if (in_band.size() < 2) return 0.0;
  Eigen::Vector3d rest_mean = Eigen::Vector3d::Zero(), morphed_mean = Eigen::Vector3d::Zero();
  for (int v : in_band) {
    rest_mean += rest.V.col(v);
    morphed_mean += morphed.V.col(v);
  }
  rest_mean /= static_cast<double>(in_band.size());
  morphed_mean /= static_cast<double>(in_band.size());
  double rest_spread = 0.0, morphed_spread = 0.0;
  for (int v : in_band) {
    rest_spread += (rest.V.col(v) - rest_mean).squaredNorm();
    morphed_spread += (morphed.V.col(v) - morphed_mean).squaredNorm();
  }
  return rest_spread > 0 ? std::sqrt(morphed_spread / rest_spread) : 0.0;
}

struct BandSlide {
  double along = 0.0;  ///< where the cut sits along its normal from the line's centroid
  double error = 0.0;  ///< its standard error
};

// Registers the template's band either side of @p cut to the target's plane points there,
// in the template's frame: each point p is mapped back through the morph's local turn and
// scale about the line's centroids (rest @p extent.centre, target @p target_centre), then
// matched to the nearest template band vertex, point to plane, under the model
//   p~ = c + (k u - delta) n + h w + a e1 + b e2 + t1 e1 x (p - c) + t2 e2 x (p - c),
//   u = n.(p - c),  w = (p - c) - u n,
// with n the cut's normal and e1, e2 across it: a shift delta along the cut, stretches k
// along it and h across it (priors N(1, stretch_sigma^2)), a sideways shift and a small
// tilt about either axis across the cut (priors N(0, tilt_sigma^2)). Linear in the
// unknowns, so each round is a 7 by 7 solve; pairs beyond 3 median residuals are left
// out. While the pairs are chosen the shift has the prior N(0, slide_sigma^2) (the morph's
// placement), so a band that says little does not wander; the reading returned is what the
// chosen pairs say without it, for TransferCuts to weigh against the other cuts'.
// Neighbouring plane points share target points, so their residuals are not independent:
// the residual variance is counted @p shared times, for the priors and the error. A plane
// point paired with band vertex v is taken to lie @p outward(v) inside the surface (empty:
// nowhere). Returns where the cut (u~ = 0) lies, u = delta / k, and its standard error, both
// in template units; empty when too few points take part, the fit leaves its bounds or the
// band fixes no shift.
std::optional<BandSlide> FitBandSlide(const io::CutAnnotation& cut, const LineExtent& extent,
                                      const io::TriangleMesh& rest,
                                      const Eigen::Matrix3Xd& rest_normals,
                                      const Eigen::Matrix3d& turn, double scale,
                                      const Eigen::Vector3d& target_centre,
                                      const Eigen::Matrix3Xd& plane_points, double band,
                                      double margin, double stretch_sigma, double slide_sigma,
                                      double tilt_sigma, int shared,
                                      const Eigen::VectorXd& outward) {
  constexpr int kMinPoints = 50;
  constexpr int kRounds = 15;
  // Beyond this the fit has latched onto something else. Over 1,320 fits (bench full, seeds 1
  // and 2, every sigma, the morphs' and the true surfaces') the stretches lay within 0.9-1.1
  // for 80 % and never beyond 1.31; the one at 1.31 (leg / loin on a rig carcass) was right,
  // 0.9 mm, and dropping it at the old bound of 0.3 left the cut 6.4 mm off.
  constexpr double kMaxStretch = 0.5;
  const Eigen::Vector3d n = cut.plane.normal;
  const Eigen::Vector3d c = extent.centre;
  const Eigen::Vector3d e1 = n.unitOrthogonal();
  const Eigen::Vector3d e2 = n.cross(e1);
  std::vector<int> band_vertices;
  for (int v = 0; v < rest.num_vertices(); ++v)
    if (NearTheCut(cut, extent, rest.V.col(v), band + margin)) band_vertices.push_back(v);
  std::vector<Eigen::Vector3d> points;
  for (Eigen::Index j = 0; j < plane_points.cols(); ++j) {
    const Eigen::Vector3d p = c + turn.transpose() * (plane_points.col(j) - target_centre) / scale;
    if (NearTheCut(cut, extent, p, band)) points.push_back(p);
  }
  if (static_cast<int>(band_vertices.size()) < kMinPoints ||
      static_cast<int>(points.size()) < kMinPoints)
    return std::nullopt;
  Eigen::Matrix3Xd surface(3, static_cast<Eigen::Index>(band_vertices.size()));
  Eigen::Matrix3Xd surface_normals(3, surface.cols());
  Eigen::VectorXd surface_outward = Eigen::VectorXd::Zero(surface.cols());
  for (std::size_t i = 0; i < band_vertices.size(); ++i) {
    surface.col(static_cast<Eigen::Index>(i)) = rest.V.col(band_vertices[i]);
    surface_normals.col(static_cast<Eigen::Index>(i)) = rest_normals.col(band_vertices[i]);
    if (outward.size() != 0)
      surface_outward(static_cast<Eigen::Index>(i)) = outward(band_vertices[i]);
  }
  const PointIndex surface_index(surface);

  using Vector7d = Eigen::Matrix<double, 7, 1>;
  using Matrix7d = Eigen::Matrix<double, 7, 7>;
  Vector7d x;
  x << 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0;  // delta, k, h, a, b, tilts about e1, e2
  std::vector<Vector7d> rows(points.size());
  std::vector<double> rhs(points.size()), residual(points.size());
  Matrix7d information = Matrix7d::Identity();
  Vector7d rhs_sum = Vector7d::Zero();
  double variance = 0.0;
  for (int round = 0; round < kRounds; ++round) {
    for (std::size_t j = 0; j < points.size(); ++j) {
      const Eigen::Vector3d d = points[j] - c;
      const double u = n.dot(d);
      Eigen::Matrix<double, 3, 7> J;
      J << -n, u * n, d - u * n, e1, e2, e1.cross(d), e2.cross(d);
      const Eigen::Vector3d moved = c + J * x;
      const int k = surface_index.Nearest(moved);
      const Eigen::Vector3d normal = surface_normals.col(k);
      rows[j] = J.transpose() * normal;
      rhs[j] = normal.dot(surface.col(k) - c) - surface_outward(k);
      residual[j] = std::abs(normal.dot(moved - surface.col(k)) + surface_outward(k));
    }
    std::vector<double> sorted = residual;
    std::nth_element(sorted.begin(),
                     sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double cutoff = 3.0 * std::max(sorted[sorted.size() / 2], 1e-12);
    Matrix7d A = Matrix7d::Zero();
    Vector7d b = Vector7d::Zero();
    double sum_squares = 0.0;
    int used = 0;
    for (std::size_t j = 0; j < points.size(); ++j) {
      if (residual[j] > cutoff) continue;
      A += rows[j] * rows[j].transpose();
      b += rows[j] * rhs[j];
      sum_squares += residual[j] * residual[j];
      ++used;
    }
    if (used < kMinPoints) return std::nullopt;
    // Plane points share their neighbours, so about one in `shared` residuals is independent.
    variance = sum_squares / used * shared;
    const double prior = variance / (stretch_sigma * stretch_sigma);
    A(1, 1) += prior;
    b(1) += prior;
    A(2, 2) += prior;
    b(2) += prior;
    A(0, 0) += variance / (slide_sigma * slide_sigma);
    const double tilt_prior = variance / (tilt_sigma * tilt_sigma);
    A(5, 5) += tilt_prior;
    A(6, 6) += tilt_prior;
    x = A.ldlt().solve(b);
    information = A;
    rhs_sum = b;
  }
  if (!x.allFinite() || std::abs(x(1) - 1.0) > kMaxStretch || std::abs(x(2) - 1.0) > kMaxStretch)
    return std::nullopt;
  // The prior chose which pairs count; the reading itself is what they say without it.
  information(0, 0) -= variance / (slide_sigma * slide_sigma);
  const Eigen::LDLT<Matrix7d> ldlt(information);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return std::nullopt;
  const Vector7d reading = ldlt.solve(rhs_sum);
  const double spread = ldlt.solve(Vector7d::Unit(0))(0);
  if (!reading.allFinite() || !(spread > 0) || reading(1) <= 0) return std::nullopt;
  const double along = reading(0) / reading(1);
  const double error = std::sqrt(variance * spread) / reading(1);
  if (std::abs(along) > 0.5 * band || error > band) return std::nullopt;
  return BandSlide{.along = along, .error = error};
}

// What TransferCuts learns of one cut before the cuts are placed together.
struct CutReading {
  LineExtent extent;
  // The morph's scale about the band; 0 when no band fit was possible (no normals' turn,
  // or no band), and then the cut is not moved.
  double scale = 0.0;
  std::optional<BandSlide> band;  // the band's own reading, template units
};

// The slides of all cuts from their band readings (template units): the posterior mean and
// standard deviation under a zero-mean Gaussian prior with covariance
//   K_ij = sigma^2 exp(-(d_ij / length)^2) n_i.n_j,
// d_ij the distance between the cuts' line centroids and n their expert normals, and each
// reading's variance its standard error squared plus model_error squared. Cuts without a
// reading get what the others say of them. Returns false, every slide 0, when no cut has a
// reading.
bool PlaceTogether(const io::Annotations& annotations, const std::vector<CutReading>& readings,
                   double sigma, double length, double model_error, Eigen::VectorXd* mean,
                   Eigen::VectorXd* deviation) {
  const Eigen::Index n = static_cast<Eigen::Index>(readings.size());
  Eigen::MatrixXd K(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      const double d = (readings[i].extent.centre - readings[j].extent.centre).norm();
      const double correlation = i == j       ? 1.0
                                 : length > 0 ? std::exp(-(d / length) * (d / length))
                                              : 0.0;
      K(i, j) = sigma * sigma * correlation *
                annotations.cuts[i].plane.normal.dot(annotations.cuts[j].plane.normal);
    }
  }
  std::vector<Eigen::Index> read;
  for (Eigen::Index i = 0; i < n; ++i)
    if (readings[i].band) read.push_back(i);
  mean->setZero(n);
  *deviation = K.diagonal().cwiseSqrt();
  if (read.empty()) return false;
  const Eigen::Index m = static_cast<Eigen::Index>(read.size());
  Eigen::MatrixXd system(m, m), cross(n, m);
  Eigen::VectorXd values(m);
  for (Eigen::Index a = 0; a < m; ++a) {
    const BandSlide& band = *readings[read[a]].band;
    values(a) = band.along;
    for (Eigen::Index b = 0; b < m; ++b) system(a, b) = K(read[a], read[b]);
    system(a, a) += band.error * band.error + model_error * model_error;
    cross.col(a) = K.col(read[a]);
  }
  // K is a covariance (a product of two), so with the readings' variances this is positive
  // definite unless two cuts coincide and read exactly; then the morph's placement stands.
  const Eigen::LLT<Eigen::MatrixXd> llt(system);
  if (llt.info() != Eigen::Success) return true;
  *mean = cross * llt.solve(values);
  const Eigen::MatrixXd explained = cross * llt.solve(cross.transpose());
  *deviation = (K.diagonal() - explained.diagonal()).cwiseMax(0.0).cwiseSqrt();
  return true;
}

}  // namespace

std::vector<TransferredCut> TransferCuts(const io::Annotations& annotations,
                                         const io::TriangleMesh& rest,
                                         const io::TriangleMesh& morphed,
                                         const Eigen::Matrix3Xd& target,
                                         const Eigen::Matrix3Xd& target_normals, double size,
                                         const CutTransferOptions& options, double noise) {
  VB_DEMAND(rest.num_vertices() == morphed.num_vertices() && target.cols() > 0 &&
            target_normals.cols() == target.cols() && size > 0 && noise >= 0 &&
            options.slide_band_noise > 0 && options.slide_sigma > 0 &&
            options.slide_correlation_length >= 0 && options.slide_model_error >= 0);
  const double template_size = io::BoundingBoxDiagonal(rest.V);
  const double relative_noise = noise / options.slide_band_noise;
  const double slide_band = options.slide_band * std::sqrt(std::max(1.0, relative_noise));
  // Noisier targets average more points per plane point (see max_slide_plane_neighbours).
  const int plane_neighbours = NeighboursForNoise(
      options.slide_plane_neighbours, options.max_slide_plane_neighbours, relative_noise);
  const PointIndex index(target);
  const double radius = options.support_radius * size;
  Eigen::Matrix3Xd computed_rest_normals, computed_morphed_normals;  // for meshes without
  const Eigen::Matrix3Xd& rest_normals =
      rest.has_normals() ? rest.N : (computed_rest_normals = io::VertexNormals(rest));
  const Eigen::Matrix3Xd& morphed_normals =
      morphed.has_normals() ? morphed.N : (computed_morphed_normals = io::VertexNormals(morphed));
  Eigen::Matrix3Xd plane_points;  // of the target, made when the first band fit needs them
  // How far out along the normal a noisy target's plane point paired with each template
  // vertex is moved, template units (see unbias_plane_points); empty on a clean target.
  Eigen::VectorXd outward;
  if (options.unbias_plane_points && noise > 0) {
    const double sigma = noise * template_size;
    outward = io::CurvatureSums(rest, rest_normals).unaryExpr([sigma](double curvature) {
      return CurvatureOffset(curvature, sigma);
    });
  }
  std::vector<int> found;
  std::vector<double> distances;
  std::vector<TransferredCut> out;
  std::vector<CutReading> readings;
  for (const io::CutAnnotation& cut : annotations.cuts) {
    TransferredCut t;
    CutReading reading;
    t.name = cut.name;
    reading.extent = ExtentOf(cut, rest);
    int seen = 0;
    for (const io::SurfacePoint& sp : cut.line) {
      const Eigen::Vector3d p = io::Evaluate(morphed, sp);
      index.Nearest(p, options.surface_neighbours, &found, &distances);
      Eigen::Vector3d mean = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::Zero();
      int n = 0;
      for (std::size_t k = 0; k < found.size(); ++k) {
        if (distances[k] > radius * radius) continue;
        mean += target.col(found[k]);
        normal += target_normals.col(found[k]);
        ++n;
      }
      if (n == 0 || normal.norm() < 1e-12) {
        t.line.push_back(p);  // unseen: the morphed template stands in for the target
        continue;
      }
      mean /= n;
      normal.normalize();
      const double offset = normal.dot(p - mean);
      t.line.push_back(p - offset * normal);
      t.gap += std::abs(offset);
      ++seen;
    }
    t.coverage = cut.line.empty() ? 0.0 : static_cast<double>(seen) / cut.line.size();
    t.gap = seen ? t.gap / seen : 0.0;
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
                                         options.slide_plane_radius * size, true);
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

std::vector<io::PartMeasure> CutParts(const io::TriangleMesh& mesh,
                                      const std::vector<TransferredCut>& cuts) {
  std::vector<io::Plane> planes;
  for (const TransferredCut& c : cuts) planes.push_back(c.plane);
  return io::MeasureParts(mesh, planes);
}

namespace {

// Signed distance from @p p to @p mesh near its vertex @p v (outward positive): to the
// nearest of the faces round v that p projects into, else along v's normal. Exact where the
// closest point lies in v's one ring, which the nearest vertex's does on a mesh finer than
// its curvature.
double SignedDistanceNear(const io::TriangleMesh& mesh, const Eigen::Matrix3Xd& normals,
                          const std::vector<int>& faces_of_v, int v, const Eigen::Vector3d& p) {
  double distance = normals.col(v).dot(p - mesh.V.col(v));
  double nearest = std::numeric_limits<double>::infinity();
  for (int f : faces_of_v) {
    const Eigen::Vector3d a = mesh.V.col(mesh.F(0, f));
    const Eigen::Vector3d b = mesh.V.col(mesh.F(1, f));
    const Eigen::Vector3d c = mesh.V.col(mesh.F(2, f));
    Eigen::Vector3d n = (b - a).cross(c - a);
    const double twice_area = n.norm();
    if (!(twice_area > 0)) continue;
    n /= twice_area;
    const double height = n.dot(p - a);
    const Eigen::Vector3d q = p - height * n;
    if (n.dot((b - q).cross(c - q)) < 0 || n.dot((c - q).cross(a - q)) < 0 ||
        n.dot((a - q).cross(b - q)) < 0)
      continue;  // projects outside this face
    if (std::abs(height) < nearest) {
      nearest = std::abs(height);
      distance = height;
    }
  }
  return distance;
}

}  // namespace

std::vector<io::PartMeasure> CutTargetParts(const io::TriangleMesh& morphed,
                                            const std::vector<TransferredCut>& cuts,
                                            const Eigen::Matrix3Xd& target, double size,
                                            const PartVolumeOptions& options) {
  VB_DEMAND(size > 0 && options.max_offset > 0);
  std::vector<io::PartMeasure> parts = CutParts(morphed, cuts);
  if (parts.empty() || morphed.num_vertices() == 0) return parts;
  Eigen::Matrix3Xd computed_normals;  // for a mesh without
  const Eigen::Matrix3Xd& normals =
      morphed.has_normals() ? morphed.N : (computed_normals = io::VertexNormals(morphed));
  const std::vector<std::vector<int>> faces_of = io::FacesOfVertices(morphed);
  const PointIndex index(morphed.V);
  const double max_offset = options.max_offset * size;
  std::vector<double> sum(parts.size(), 0.0);
  std::vector<int> count(parts.size(), 0);
  for (Eigen::Index j = 0; j < target.cols(); ++j) {
    const Eigen::Vector3d p = target.col(j);
    const int v = index.Nearest(p);
    const double d =
        SignedDistanceNear(morphed, normals, faces_of[static_cast<std::size_t>(v)], v, p);
    if (!(std::abs(d) <= max_offset)) continue;
    // Part k lies on the negative side of cuts 0..k-1 and the positive side of cut k.
    std::size_t part = 0;
    while (part < cuts.size() && cuts[part].plane.SignedDistance(p) < 0) ++part;
    sum[part] += d;
    ++count[part];
  }
  for (std::size_t k = 0; k < parts.size(); ++k)
    if (count[k] >= options.min_points) parts[k].volume += parts[k].area * sum[k] / count[k];
  return parts;
}

}  // namespace vb::morph
