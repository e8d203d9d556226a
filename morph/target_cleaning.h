#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "morph/point_index.h"
#include "morph/worker_pool.h"

// Stray points and detached clutter taken out of a target cloud before the morph.
namespace vb::morph {

/// What counts as clutter. Lengths are multiples of the cloud's own point spacing (the median
/// distance from a point to its `neighbours`-th nearest neighbour) or fractions of its
/// bounding-box diagonal, so the rule holds for any sensor, density and body size.
struct CleaningOptions {
  /// Neighbours a point's spacing is read over; 0 turns the cleaning off.
  int neighbours = 8;
  /// A point whose `neighbours`-th nearest neighbour is farther than this many spacings is a
  /// stray (a depth-edge pixel, dust): dropped.
  double stray_spacings = 8.0;
  /// The other points form pieces by DBSCAN's rule with this radius in spacings: a point
  /// with all `neighbours` neighbours within it is a core point, core points within it of
  /// each other share a piece (the links are each point's `neighbours` nearest), and any
  /// other point joins its nearest core neighbour's. A piece holding fewer than `small_piece`
  /// of the largest piece's points and lying farther than `far_piece` of the body's diagonal
  /// from every larger piece (a hook, a glimpse of the next carcass) is dropped; a lone point
  /// so dropped counts as a stray. Nearer or larger pieces stay: a limb a shadow cut off is
  /// still the body. When the largest piece holds under half the points, the cloud fell apart
  /// for the neighbour graph (rows of a line scanner far apart, say) and no piece is dropped.
  double link_spacings = 4.0;
  double small_piece = 0.1;
  double far_piece = 0.05;
};

/// What the cleaning took out.
struct CleaningSummary {
  int strays = 0;          ///< points dropped as strays
  int detached = 0;        ///< points dropped in small far pieces of 2 or more
  int pieces_dropped = 0;  ///< how many such pieces
  double spacing = 0.0;    ///< the cloud's median spacing, its units (0: not read)
  double seconds = 0.0;
};

/// The cloud with its clutter taken out.
struct CleanedTarget {
  Eigen::Matrix3Xd points;   ///< the kept points, in their input order
  Eigen::Matrix3Xd normals;  ///< theirs, when normals were given (else empty)
  std::vector<int> kept;     ///< input column of each kept point
  CleaningSummary summary;
};

/// Takes stray points and small detached pieces out of @p points (3 by N, any units).
/// @p normals is 3 by N or empty. Clouds of fewer than 2 (neighbours + 1) points, with a
/// non-finite coordinate, or with cleaning off, come back whole.
/// @param[out] index when given and nothing was taken out, receives the kd-tree the cleaning
///   built over @p points (which must then outlive it), for the stages to reuse; else null.
/// @param pool when given, the neighbour search shares its threads (same result).
CleanedTarget CleanTarget(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                          const CleaningOptions& options = {},
                          std::unique_ptr<PointIndex>* index = nullptr, WorkerPool* pool = nullptr);

}  // namespace vb::morph
