#include "morph/target_cleaning.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <boost/geometry.hpp>
#include <boost/geometry/geometries/point_xy.hpp>
#include <boost/pending/disjoint_sets.hpp>
#include <chrono>
#include <cmath>
#include <limits>

#include "geometry/mesh_measures.h"
#include "io/error.h"
#include "morph/cloud_noise.h"
#include "morph/order_statistic.h"
#include "morph/point_index.h"

namespace vb::morph {
namespace {

// The body's shadow on a plane: the body's points projected onto it, as (u, v, 0) in the
// plane's unit axes along and other about origin, with a kd-tree over them. Cloud units.
class PlaneShadow {
 public:
  PlaneShadow(const Eigen::Matrix3Xd& body, const Eigen::Vector3d& along,
              const Eigen::Vector3d& other, const Eigen::Vector3d& origin)
      : along_(along),
        other_(other),
        origin_(origin),
        points_(Project(body, along, other, origin)),
        index_(points_) {}

  // @p x in the plane's axes (its third coordinate 0).
  Eigen::Vector3d InPlane(const Eigen::Vector3d& x) const {
    return {along_.dot(x - origin_), other_.dot(x - origin_), 0.0};
  }
  // How far @p in_plane (InPlane's) lies from the shadow's nearest point.
  double Distance(const Eigen::Vector3d& in_plane) const {
    return (points_.col(index_.Nearest(in_plane)) - in_plane).norm();
  }
  const Eigen::Matrix3Xd& points() const { return points_; }

 private:
  static Eigen::Matrix3Xd Project(const Eigen::Matrix3Xd& body, const Eigen::Vector3d& along,
                                  const Eigen::Vector3d& other, const Eigen::Vector3d& origin) {
    Eigen::Matrix3Xd projected = Eigen::Matrix3Xd::Zero(3, body.cols());
    projected.row(0) = along.transpose() * (body.colwise() - origin);
    projected.row(1) = other.transpose() * (body.colwise() - origin);
    return projected;
  }

  Eigen::Vector3d along_, other_, origin_;
  Eigen::Matrix3Xd points_;
  PointIndex index_;  // over points_, declared after it
};

// The pieces of @p piece_of (each kept point's piece, -1 for a dropped one) that are floors or
// walls (CleaningOptions::flat_thickness): their points are no longer kept or in a piece, and
// the piece's size becomes 0. @p link_limit: the distance that links points into a piece.
void DropFlatPieces(const Eigen::Matrix3Xd& points, const CleaningOptions& options,
                    double link_limit, std::vector<int>* piece_of, std::vector<int>* piece_size,
                    std::vector<char>* keep, CleaningSummary* summary) {
  if (!(options.flat_thickness > 0.0)) return;
  constexpr double kOtherSide = 0.01;  // of the body's points, on a floor's other side
  constexpr double kParallel = 0.95;   // cosine between two rows' normals
  const Eigen::Index n = points.cols();
  std::vector<int>& piece = *piece_of;
  std::vector<int>& size_of = *piece_size;
  // Each piece's centroid and principal axes, from its points' sums about its first point
  // (so coordinates far from the origin lose no precision).
  std::vector<int> slot(static_cast<std::size_t>(n), -1);
  std::vector<int> roots;
  for (Eigen::Index p = 0; p < n; ++p) {
    if (size_of[static_cast<std::size_t>(p)] < 4) continue;  // no plane in 3 points
    slot[static_cast<std::size_t>(p)] = static_cast<int>(roots.size());
    roots.push_back(static_cast<int>(p));
  }
  if (roots.size() < 2) return;  // flat or not, a lone piece is the body
  std::vector<Eigen::Vector3d> origin(roots.size()), sum(roots.size(), Eigen::Vector3d::Zero());
  std::vector<Eigen::Matrix3d> outer(roots.size(), Eigen::Matrix3d::Zero());
  std::vector<char> started(roots.size(), 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    const int p = piece[static_cast<std::size_t>(i)];
    if (p < 0 || slot[static_cast<std::size_t>(p)] < 0) continue;
    const auto s = static_cast<std::size_t>(slot[static_cast<std::size_t>(p)]);
    if (!started[s]) {
      origin[s] = points.col(i);
      started[s] = 1;
    }
    const Eigen::Vector3d x = points.col(i) - origin[s];
    sum[s] += x;
    outer[s] += x * x.transpose();
  }
  struct Shape {
    Eigen::Vector3d centre, normal, along;
    double thickness = 0.0, width = 0.0;  // standard deviations across the plane and along it
    bool thin = false;
  };
  std::vector<Shape> shapes(roots.size());
  int body = -1;  // slot of the largest piece that is not thin
  for (std::size_t s = 0; s < roots.size(); ++s) {
    const double count = size_of[static_cast<std::size_t>(roots[s])];
    Shape& shape = shapes[s];
    const Eigen::Vector3d mean = sum[s] / count;
    shape.centre = origin[s] + mean;
    const Eigen::Matrix3d covariance = outer[s] / count - mean * mean.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
    const Eigen::Vector3d spread = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();  // ascending
    shape.normal = eigen.eigenvectors().col(0);
    shape.along = eigen.eigenvectors().col(1);
    shape.thickness = spread(0);
    shape.width = spread(1);
    shape.thin = spread(0) <= options.flat_thickness * spread(1);
    if (!shape.thin &&
        (body < 0 ||
         count > size_of[static_cast<std::size_t>(roots[static_cast<std::size_t>(body)])]))
      body = static_cast<int>(s);
  }
  if (body < 0) return;  // all flat: nothing to judge a floor by
  // None flat (a carcass and its clutter): the body's points are not gathered.
  if (std::none_of(shapes.begin(), shapes.end(), [](const Shape& shape) { return shape.thin; }))
    return;
  const int body_root = roots[static_cast<std::size_t>(body)];
  const int body_size = size_of[static_cast<std::size_t>(body_root)];
  std::vector<int> body_columns;
  body_columns.reserve(static_cast<std::size_t>(body_size));
  for (Eigen::Index i = 0; i < n; ++i)
    if (piece[static_cast<std::size_t>(i)] == body_root)
      body_columns.push_back(static_cast<int>(i));
  const Eigen::Matrix3Xd body_points = points(Eigen::all, body_columns);
  const double diagonal = geometry::BoundingBoxDiagonal(body_points);
  // The thin pieces wide beside the body, with the body on one side of their plane.
  std::vector<std::size_t> candidates;
  for (std::size_t s = 0; s < roots.size(); ++s) {
    const Shape& shape = shapes[s];
    if (!shape.thin || std::sqrt(12.0) * shape.width < options.flat_width * diagonal) continue;
    // Beyond three of the plane's own deviations: clearly on one side.
    const Eigen::ArrayXd d =
        (shape.normal.transpose() * (body_points.colwise() - shape.centre)).transpose().array();
    const long above = (d > 3.0 * shape.thickness).count();
    const long below = (d < -3.0 * shape.thickness).count();
    if (static_cast<double>(std::min(above, below)) <= kOtherSide * body_size)
      candidates.push_back(s);
  }
  if (candidates.empty()) return;
  // A floor reaches out around the body: at least half its points lie farther than the link
  // limit from the body's shadow on its plane (a split carcass's face lies under the carcass).
  std::vector<char> floor(roots.size(), 0), candidate(roots.size(), 0);
  for (std::size_t s : candidates) candidate[s] = 1;
  std::vector<std::vector<int>> members(roots.size());
  for (Eigen::Index i = 0; i < n; ++i) {
    const int p = piece[static_cast<std::size_t>(i)];
    if (p < 0 || slot[static_cast<std::size_t>(p)] < 0) continue;
    const auto s = static_cast<std::size_t>(slot[static_cast<std::size_t>(p)]);
    if (candidate[s]) members[s].push_back(static_cast<int>(i));
  }
  for (std::size_t s : candidates) {
    const Shape& shape = shapes[s];
    const Eigen::Vector3d other = shape.normal.cross(shape.along);
    const PlaneShadow shadow(body_points, shape.along, other, Eigen::Vector3d::Zero());
    long outside = 0;
    for (int i : members[s]) outside += shadow.Distance(shadow.InPlane(points.col(i))) > link_limit;
    if (2 * outside < static_cast<long>(members[s].size())) continue;
    floor[s] = 1;
  }
  // Two of them in parallel planes apart (a floor in pieces lies in one plane, a wall across
  // it) are rows of a line scanner, each in its own plane, that the neighbour graph could not
  // join: none goes.
  for (std::size_t s : candidates) {
    for (std::size_t t : candidates) {
      if (t <= s || !floor[s] || !floor[t]) continue;
      const Shape& a = shapes[s];
      if (std::abs(a.normal.dot(shapes[t].normal)) > kParallel &&
          std::abs(a.normal.dot(shapes[t].centre - a.centre)) > link_limit)
        return;
    }
  }
  for (std::size_t s = 0; s < roots.size(); ++s) {
    if (!floor[s]) continue;
    for (int i : members[s]) {
      (*keep)[static_cast<std::size_t>(i)] = 0;
      piece[static_cast<std::size_t>(i)] = -1;
    }
    summary->flat += size_of[static_cast<std::size_t>(roots[s])];
    ++summary->flat_pieces;
    size_of[static_cast<std::size_t>(roots[s])] = 0;
  }
}

using Point2 = boost::geometry::model::d2::point_xy<double>;
using Polygon = boost::geometry::model::polygon<Point2>;

// A plane found among the kept points: its centre and unit normal, and the band about it
// (its points' distance limit).
struct Plane {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero(), normal = Eigen::Vector3d::UnitZ();
  double band = 0.0;
  long count = 0;  // sample points within the band
};

// The centroid and principal axes of the columns @p columns of @p points, from sums about the
// first of them (so coordinates far from the origin lose no precision); eigenvalues ascending.
template <typename Columns>
Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> Principal(const Eigen::Matrix3Xd& points,
                                                         const Columns& columns,
                                                         Eigen::Vector3d* centre) {
  const Eigen::Vector3d origin = points.col(*columns.begin());
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  double count = 0.0;
  for (const auto i : columns) {
    const Eigen::Vector3d x = points.col(i) - origin;
    sum += x;
    outer += x * x.transpose();
    count += 1.0;
  }
  const Eigen::Vector3d mean = sum / count;
  *centre = origin + mean;
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(outer / count - mean * mean.transpose());
}

// Floors and walls, found as planes among the kept points before the pieces: one the body
// rests on or leans on, in one piece with it, and one apart from it alike (DropFlatPieces then
// judges what is left). A plane is started at each of kSeeds points spread over the kept points
// (the best plane of its kSeedNeighbours nearest) and refitted to a sample of at most kSample
// of them within its band, three times their deviation across it (read from their median
// distance; at least two spacings; a band that grows to the link limit is a curved surface,
// not a plane). The plane holding most
// of the sample goes when: it is thin against its width and wide against the body's diagonal
// (flat_thickness, flat_width); at most 1 % of the body's points lie beyond twice its band on
// its far side; the body stands off it (the 90th percentile of its distances from the plane
// at least kStandsOff of its diagonal); half its points lie out of the body's shadow (beyond
// the link limit from it and outside its convex hull: not the cut face of a split carcass seen
// with its rim round it); it is a sheet (on a grid of link-limit cells over it, at least half the
// cells holding its points have all 8 neighbours holding its points or under the body's shadow: a
// spider's legs spread in one plane are strips); and the centre of the body's shadow lies in the
// box of the cells reached from those inner cells through cells holding its points (a floor reaches
// round the body; a flat flap of it lies beside it). What goes: its points in the reached cells
// (the body's touching cap where its cells join them), and the points within twice the band out of
// the body's shadow there (its noise's stragglers; a thin limb lying on it too). It counts as
// a flat piece, and the search runs again, up to options.touching_planes times, stopping at
// the first plane that fails (a larger flat part of the body that fails hides a floor).
void DropTouchingPlanes(const Eigen::Matrix3Xd& points, const PointIndex& index,
                        const CleaningOptions& options, double spacing, double link_limit,
                        std::vector<char>* keep, CleaningSummary* summary) {
  if (options.touching_planes <= 0 || !(options.flat_thickness > 0.0)) return;
  constexpr Eigen::Index kSample = 1024;  // points the planes are fitted and scored on
  constexpr int kSeeds = 64;
  constexpr int kSeedNeighbours = 32;
  constexpr int kRefits = 6;
  constexpr double kOtherSide = 0.01;  // of the body's points, on a floor's other side
  constexpr double kStandsOff = 0.05;  // of the body's diagonal
  const double min_band = std::min(2.0 * spacing, link_limit);
  constexpr double kCells = 256.0;
  std::vector<int> kept_columns, plane_columns, body_columns, found;
  std::vector<char> grid;
  boost::geometry::model::multi_point<Point2> hull_points;
  std::vector<std::pair<int, int>> flood;
  std::vector<double> squared, distances;
  for (int round = 0; round < options.touching_planes; ++round) {
    kept_columns.clear();
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      if ((*keep)[static_cast<std::size_t>(i)]) kept_columns.push_back(static_cast<int>(i));
    const auto kept = static_cast<Eigen::Index>(kept_columns.size());
    if (kept < 4 * kSeedNeighbours) return;
    const Eigen::Index stride = (kept + kSample - 1) / kSample;
    Eigen::Matrix3Xd sample(3, (kept + stride - 1) / stride);
    for (Eigen::Index k = 0; k < sample.cols(); ++k)
      sample.col(k) = points.col(kept_columns[static_cast<std::size_t>(k * stride)]);
    Plane best;
    std::vector<Eigen::Index> inside;
    for (int s = 0; s < kSeeds; ++s) {
      const Eigen::Vector3d seed = sample.col(sample.cols() * s / kSeeds);
      index.Nearest(seed, kSeedNeighbours, &found, &squared);
      std::erase_if(found, [&](int i) { return !(*keep)[static_cast<std::size_t>(i)]; });
      if (found.size() < 3) continue;
      Plane plane;
      plane.normal = Principal(points, found, &plane.centre).eigenvectors().col(0);
      plane.band = min_band;
      bool curved = false;
      for (int refit = 0; refit <= kRefits && !curved; ++refit) {
        inside.clear();
        for (Eigen::Index k = 0; k < sample.cols(); ++k)
          if (std::abs(plane.normal.dot(sample.col(k) - plane.centre)) <= plane.band)
            inside.push_back(k);
        plane.count = static_cast<long>(inside.size());
        if (refit == kRefits || inside.size() < 3) break;
        plane.normal = Principal(sample, inside, &plane.centre).eigenvectors().col(0);
        // The deviation across it from the median distance: the body's touching cap in the
        // band, a minority, moves a median little.
        distances.clear();
        for (const Eigen::Index k : inside)
          distances.push_back(std::abs(plane.normal.dot(sample.col(k) - plane.centre)));
        const double band = 3.0 * kMadToSigma * SelectUpperMedian(distances);
        curved = band >= link_limit;
        plane.band = std::clamp(band, min_band, link_limit);
      }
      if (!curved && plane.count > best.count) best = plane;
    }
    if (best.count < 3) return;
    // The plane's kept points and the body's (the rest), over the whole cloud.
    plane_columns.clear();
    body_columns.clear();
    for (const int i : kept_columns)
      (std::abs(best.normal.dot(points.col(i) - best.centre)) <= best.band ? plane_columns
                                                                           : body_columns)
          .push_back(i);
    if (plane_columns.size() < 3 || body_columns.empty()) return;
    Eigen::Vector3d centre;
    const auto eigen = Principal(points, plane_columns, &centre);
    const Eigen::Vector3d spread = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt();
    const Eigen::Vector3d normal = eigen.eigenvectors().col(0);
    const Eigen::Vector3d along = eigen.eigenvectors().col(1);
    const Eigen::Vector3d other = normal.cross(along);
    if (spread(0) > options.flat_thickness * spread(1)) return;
    const Eigen::Matrix3Xd body = points(Eigen::all, body_columns);
    const Eigen::ArrayXd side =
        (normal.transpose() * (body.colwise() - centre)).transpose().array();
    // Beyond twice the band: the plane's own noise leaves a few of its points (0.3 % at three
    // deviations) just beyond the band on both sides, as many as 1 % of the body's when the
    // plane holds a few times its points.
    const long above = (side > 2.0 * best.band).count();
    const long below = (side < -2.0 * best.band).count();
    if (static_cast<double>(std::min(above, below)) > kOtherSide * static_cast<double>(body.cols()))
      return;
    // The body proper: its points beyond twice the band, since the plane's stragglers just
    // beyond the band lie scattered over its whole width.
    std::vector<Eigen::Index> clear;
    for (Eigen::Index b = 0; b < body.cols(); ++b)
      if (std::abs(side(b)) > 2.0 * best.band) clear.push_back(b);
    if (clear.empty()) return;
    const Eigen::Matrix3Xd standing = body(Eigen::all, clear);
    const double diagonal = geometry::BoundingBoxDiagonal(standing);
    if (std::sqrt(12.0) * spread(1) < options.flat_width * diagonal) return;
    // A body resting on a floor or leaning on a wall stands off it: the 90th percentile of its
    // points' distances from the plane is at least kStandsOff of its diagonal. The cut face of
    // a split carcass scanned from that side alone, with only its rim beside it, does not.
    distances.assign(side.data(), side.data() + side.size());
    for (double& d : distances) d = std::abs(d);
    if (SelectQuantile(distances, 0.9) < kStandsOff * diagonal) return;
    // The body's shadow on the plane, in the plane's axes about its centre.
    const PlaneShadow shadow(standing, along, other, centre);
    const Eigen::Vector2d shadow_centre = shadow.points().topRows<2>().rowwise().mean();
    // Its points out of the body's shadow: farther than the link limit from it and outside its
    // convex hull (the cut face of a split carcass seen with its rim lies within the rim's), and
    // their extent (the touching cap is in the band too).
    hull_points.clear();
    for (Eigen::Index b = 0; b < shadow.points().cols(); ++b)
      hull_points.emplace_back(shadow.points()(0, b), shadow.points()(1, b));
    Polygon hull;
    boost::geometry::convex_hull(hull_points, hull);
    Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d high = -low;
    long outside = 0;
    for (const int i : plane_columns) {
      const Eigen::Vector3d x = shadow.InPlane(points.col(i));
      if (shadow.Distance(x) <= link_limit || boost::geometry::within(Point2(x(0), x(1)), hull))
        continue;
      ++outside;
      low = low.cwiseMin(x.head<2>());
      high = high.cwiseMax(x.head<2>());
    }
    if (2 * outside < static_cast<long>(plane_columns.size())) return;
    // A floor is a sheet: on a grid over the box of its points out of the body's shadow
    // (link-limit cells, coarser when that would make more than kCells a side), at least half
    // the cells that hold its points have all 8 neighbours holding its points or under the
    // body's shadow (what the body hides of it). Limbs spread flat in one plane (a spider's
    // legs) are strips a cell or two wide, with few such cells.
    const double cell = std::max(link_limit, (high - low).maxCoeff() / kCells);
    const Eigen::Array2i cells = ((high - low) / cell).array().cast<int>() + 1;
    grid.assign(static_cast<std::size_t>(cells(0)) * static_cast<std::size_t>(cells(1)), 0);
    const auto at = [&](int u, int v) -> char& {
      return grid[static_cast<std::size_t>(v) * static_cast<std::size_t>(cells(0)) +
                  static_cast<std::size_t>(u)];
    };
    // The cell of @p x, or (-1, -1) beyond the grid (checked before the cast to int).
    const auto cell_of = [&](const Eigen::Vector2d& x) {
      const Eigen::Array2d c = ((x - low) / cell).array().floor();
      if ((c < 0.0).any() || (c >= cells.cast<double>()).any()) return Eigen::Array2i(-1, -1);
      return Eigen::Array2i(c.cast<int>());
    };
    const auto mark = [&](const Eigen::Vector2d& x, char bit) {
      const Eigen::Array2i c = cell_of(x);
      if (c(0) >= 0) at(c(0), c(1)) |= bit;
    };
    for (const int i : plane_columns) mark(shadow.InPlane(points.col(i)).head<2>(), 1);
    for (Eigen::Index b = 0; b < shadow.points().cols(); ++b)
      mark(shadow.points().col(b).head<2>(), 2);
    long holding = 0, inner = 0;
    flood.clear();
    for (int v = 0; v < cells(1); ++v)
      for (int u = 0; u < cells(0); ++u) {
        if (!(at(u, v) & 1)) continue;
        ++holding;
        bool surrounded = u > 0 && v > 0 && u + 1 < cells(0) && v + 1 < cells(1);
        for (int dv = -1; dv <= 1 && surrounded; ++dv)
          for (int du = -1; du <= 1 && surrounded; ++du) surrounded = at(u + du, v + dv) != 0;
        if (!surrounded) continue;
        ++inner;
        flood.emplace_back(u, v);
      }
    if (2 * inner < holding || inner == 0) return;
    // The sheet: the cells holding its points reached from its inner cells through cells that
    // hold its points. A limb crossing its plane more than a cell beyond its edge is not
    // reached; the body's touching cap is where its cells join the sheet's.
    constexpr char kSheet = 4;
    for (const auto& [u, v] : flood) at(u, v) |= kSheet;
    while (!flood.empty()) {
      const auto [u, v] = flood.back();
      flood.pop_back();
      for (int dv = -1; dv <= 1; ++dv)
        for (int du = -1; du <= 1; ++du) {
          const int x = u + du, y = v + dv;
          if (x < 0 || y < 0 || x >= cells(0) || y >= cells(1) || (at(x, y) & kSheet) ||
              !(at(x, y) & 1))
            continue;
          at(x, y) |= kSheet;
          flood.emplace_back(x, y);
        }
    }
    // A floor reaches round the body: the centre of the body's shadow lies within the sheet's
    // box (a flat flap of the body, a wing, lies beside the body's shadow).
    Eigen::Array2d sheet_low = Eigen::Array2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Array2d sheet_high = -sheet_low;
    for (int v = 0; v < cells(1); ++v)
      for (int u = 0; u < cells(0); ++u) {
        if (!(at(u, v) & kSheet)) continue;
        sheet_low = sheet_low.min(low.array() + cell * Eigen::Array2d(u, v));
        sheet_high = sheet_high.max(low.array() + cell * Eigen::Array2d(u + 1, v + 1));
      }
    if ((shadow_centre.array() < sheet_low).any() || (shadow_centre.array() > sheet_high).any())
      return;
    // It goes with its points in the sheet, and the stragglers its noise left just beyond the
    // band, out on the sheet away from the body's shadow (else each is a piece of its own,
    // apart from the body).
    const auto on_it = [&](const Eigen::Vector3d& p) {
      const Eigen::Array2i c = cell_of(shadow.InPlane(p).head<2>());
      return c(0) >= 0 && (at(c(0), c(1)) & kSheet);
    };
    int taken = 0;
    for (const int i : plane_columns) {
      if (!on_it(points.col(i))) continue;
      (*keep)[static_cast<std::size_t>(i)] = 0;
      ++taken;
    }
    for (Eigen::Index b = 0; b < body.cols(); ++b) {
      if (std::abs(side(b)) > 2.0 * best.band || !on_it(body.col(b))) continue;
      if (shadow.Distance(shadow.InPlane(body.col(b))) <= link_limit) continue;
      (*keep)[static_cast<std::size_t>(body_columns[static_cast<std::size_t>(b)])] = 0;
      ++taken;
    }
    summary->flat += taken;
    ++summary->flat_pieces;
  }
}
}  // namespace

CleanedTarget CleanTarget(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                          const CleaningOptions& options, std::unique_ptr<PointIndex>* index_out,
                          WorkerPool* pool, Eigen::Index template_vertices) {
  const auto start = std::chrono::steady_clock::now();
  if (index_out != nullptr) index_out->reset();
  VB_DEMAND(normals.cols() == 0 || normals.cols() == points.cols());
  VB_DEMAND(options.neighbours >= 0 && options.stray_spacings > 0 && options.link_spacings > 0 &&
            options.small_piece >= 0 && options.far_piece >= 0 && options.flat_thickness >= 0 &&
            options.flat_width >= 0 && options.touching_planes >= 0 &&
            options.max_points_per_vertex >= 0 && template_vertices >= 0);
  const Eigen::Index n = points.cols();
  // Far denser than the template: every stride-th point, then cleaned as a cloud of its own.
  const double cap = options.max_points_per_vertex * static_cast<double>(template_vertices);
  if (cap >= 1.0 && static_cast<double>(n) > cap && points.allFinite()) {
    const auto stride = static_cast<Eigen::Index>(std::ceil(static_cast<double>(n) / cap));
    const auto every = Eigen::seq(0, Eigen::last, stride);
    CleanedTarget out =
        CleanTarget(points(Eigen::all, every),
                    normals.cols() != 0 ? Eigen::Matrix3Xd(normals(Eigen::all, every)) : normals,
                    options, nullptr, pool, 0);
    for (int& column : out.kept) column *= static_cast<int>(stride);
    for (int& column : out.detached) column *= static_cast<int>(stride);
    out.summary.stride = static_cast<int>(stride);
    out.summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return out;
  }
  const int k = options.neighbours;
  CleanedTarget out;
  const auto keep_all = [&] {
    out.points = points;
    out.normals = normals;
    out.kept.resize(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i)
      out.kept[static_cast<std::size_t>(i)] = static_cast<int>(i);
    out.summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  // Non-finite coordinates have no neighbours to read: left for the stages to name.
  if (k == 0 || n < 2 * (k + 1) || !points.allFinite()) {
    keep_all();
    return out;
  }

  // Each point's k nearest others and the distance to the k-th of them.
  auto owned_index = std::make_unique<PointIndex>(points);
  const PointIndex& index = *owned_index;
  Eigen::MatrixXi near(k, n);
  Eigen::MatrixXd near_distance(k, n);
  std::vector<double> spacing(static_cast<std::size_t>(n));
  // In blocks on the pool's threads, each writing only its own columns.
  constexpr int kBlocks = 16;
  ForEach(pool, kBlocks, [&](int block) {
    std::vector<int> found;
    std::vector<double> squared;
    for (Eigen::Index i = n * block / kBlocks; i < n * (block + 1) / kBlocks; ++i) {
      index.Nearest(points.col(i), k + 1, &found, &squared);
      int m = 0;
      for (std::size_t f = 0; f < found.size() && m < k; ++f) {
        if (found[f] == i) continue;  // the point itself (a duplicate may come first)
        near(m, i) = found[f];
        near_distance(m, i) = std::sqrt(squared[f]);
        ++m;
      }
      for (; m < k; ++m) {  // not reached: n > k
        near(m, i) = static_cast<int>(i);
        near_distance(m, i) = 0.0;
      }
      spacing[static_cast<std::size_t>(i)] = near_distance(k - 1, i);
    }
  });
  std::vector<double> sorted = spacing;
  out.summary.spacing = SelectUpperMedian(sorted);
  if (!(out.summary.spacing > 0)) {  // most points coincide: nothing to read
    keep_all();
    return out;
  }

  std::vector<char> keep(static_cast<std::size_t>(n), 1);
  const double stray_limit = options.stray_spacings * out.summary.spacing;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (spacing[static_cast<std::size_t>(i)] > stray_limit) {
      keep[static_cast<std::size_t>(i)] = 0;
      ++out.summary.strays;
    }
  }

  // A floor or wall the body touches, in one piece with it, first: the pieces are then found
  // without it.
  const double link_limit = options.link_spacings * out.summary.spacing;
  DropTouchingPlanes(points, index, options, out.summary.spacing, link_limit, &keep, &out.summary);

  // Pieces, by DBSCAN's rule (radius link_spacings, k neighbours): a core point has all its k
  // neighbours within the link limit, and core points within it of each other are one piece.
  // Every other kept point joins the piece of its nearest core neighbour within the limit, or
  // stands alone, so a sparse point between two pieces (a stray near both) cannot join them.
  std::vector<char> core(static_cast<std::size_t>(n), 0);
  for (Eigen::Index i = 0; i < n; ++i)
    core[static_cast<std::size_t>(i)] =
        keep[static_cast<std::size_t>(i)] && near_distance(k - 1, i) <= link_limit;
  boost::disjoint_sets_with_storage<> pieces(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!keep[static_cast<std::size_t>(i)]) continue;
    for (int m = 0; m < k; ++m) {
      const int j = near(m, i);
      if (!core[static_cast<std::size_t>(j)] || near_distance(m, i) > link_limit) continue;
      pieces.union_set(static_cast<std::size_t>(i), static_cast<std::size_t>(j));
      if (!core[static_cast<std::size_t>(i)]) break;  // a border point joins one piece only
    }
  }
  std::vector<int> piece(static_cast<std::size_t>(n), -1);
  std::vector<int> piece_size(static_cast<std::size_t>(n), 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!keep[static_cast<std::size_t>(i)]) continue;
    piece[static_cast<std::size_t>(i)] =
        static_cast<int>(pieces.find_set(static_cast<std::size_t>(i)));
    ++piece_size[static_cast<std::size_t>(piece[static_cast<std::size_t>(i)])];
  }
  DropFlatPieces(points, options, link_limit, &piece, &piece_size, &keep, &out.summary);
  const int largest =
      static_cast<int>(std::max_element(piece_size.begin(), piece_size.end()) - piece_size.begin());
  const int largest_size = piece_size[static_cast<std::size_t>(largest)];
  const long kept_count = std::count(keep.begin(), keep.end(), 1);
  const auto is_small = [&](int p) {
    const int size = piece_size[static_cast<std::size_t>(p)];
    return size > 0 && size < options.small_piece * largest_size;
  };
  std::vector<int> small;
  for (Eigen::Index p = 0; p < n; ++p)
    if (is_small(static_cast<int>(p))) small.push_back(static_cast<int>(p));
  // A cloud whose largest piece is under half of it fell apart for the neighbour graph (rows
  // of a line scanner farther apart than 4 spacings, say): the pieces say nothing then.
  if (!small.empty() && 2 * static_cast<long>(largest_size) >= kept_count) {
    // The small pieces' gaps to the pieces that are not small (the body, and a limb a shadow
    // cut off as large as a tenth of it), and the limit on the body's diagonal: the strays'
    // box is not the body's.
    std::vector<int> body_columns;
    for (Eigen::Index i = 0; i < n; ++i) {
      const int p = piece[static_cast<std::size_t>(i)];
      if (p >= 0 && !is_small(p)) body_columns.push_back(static_cast<int>(i));
    }
    const Eigen::Matrix3Xd body = points(Eigen::all, body_columns);
    const PointIndex body_index(body);
    const double far_limit = options.far_piece * geometry::BoundingBoxDiagonal(body);
    std::vector<double> gap(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
    for (Eigen::Index i = 0; i < n; ++i) {
      const int p = piece[static_cast<std::size_t>(i)];
      if (p < 0 || !is_small(p)) continue;
      const double d = (body.col(body_index.Nearest(points.col(i))) - points.col(i)).norm();
      gap[static_cast<std::size_t>(p)] = std::min(gap[static_cast<std::size_t>(p)], d);
    }
    std::vector<char> dropped(static_cast<std::size_t>(n), 0);
    for (int p : small) {
      if (gap[static_cast<std::size_t>(p)] <= far_limit) continue;
      dropped[static_cast<std::size_t>(p)] = 1;
      const int size = piece_size[static_cast<std::size_t>(p)];
      if (size == 1) {  // a lone point is a stray, whatever its neighbours' spacing
        ++out.summary.strays;
      } else {
        ++out.summary.pieces_dropped;
        out.summary.detached += size;
      }
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      const int p = piece[static_cast<std::size_t>(i)];
      if (p < 0 || !dropped[static_cast<std::size_t>(p)]) continue;
      keep[static_cast<std::size_t>(i)] = 0;
      if (piece_size[static_cast<std::size_t>(p)] > 1) out.detached.push_back(static_cast<int>(i));
    }
  }

  if (Removed(out.summary) == 0) {
    if (index_out != nullptr) *index_out = std::move(owned_index);
    keep_all();
    return out;
  }
  for (Eigen::Index i = 0; i < n; ++i)
    if (keep[static_cast<std::size_t>(i)]) out.kept.push_back(static_cast<int>(i));
  out.points = points(Eigen::all, out.kept);
  if (normals.cols() != 0) out.normals = normals(Eigen::all, out.kept);
  out.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace vb::morph
