#include "morph/target_cleaning.h"

#include <algorithm>
#include <boost/pending/disjoint_sets.hpp>
#include <chrono>
#include <cmath>
#include <limits>

#include "geometry/mesh_measures.h"
#include "io/error.h"
#include "morph/point_index.h"

namespace vb::morph {

CleanedTarget CleanTarget(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                          const CleaningOptions& options, std::unique_ptr<PointIndex>* index_out,
                          WorkerPool* pool, Eigen::Index template_vertices) {
  const auto start = std::chrono::steady_clock::now();
  if (index_out != nullptr) index_out->reset();
  VB_DEMAND(normals.cols() == 0 || normals.cols() == points.cols());
  VB_DEMAND(options.neighbours >= 0 && options.stray_spacings > 0 && options.link_spacings > 0 &&
            options.small_piece >= 0 && options.far_piece >= 0 &&
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
  const auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
  std::nth_element(sorted.begin(), middle, sorted.end());
  out.summary.spacing = *middle;
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

  // Pieces, by DBSCAN's rule (radius link_spacings, k neighbours): a core point has all its k
  // neighbours within the link limit, and core points within it of each other are one piece.
  // Every other kept point joins the piece of its nearest core neighbour within the limit, or
  // stands alone, so a sparse point between two pieces (a stray near both) cannot join them.
  const double link_limit = options.link_spacings * out.summary.spacing;
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
      if (p >= 0 && dropped[static_cast<std::size_t>(p)]) keep[static_cast<std::size_t>(i)] = 0;
    }
  }

  if (out.summary.strays + out.summary.detached == 0) {
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
