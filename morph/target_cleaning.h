#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "morph/point_index.h"
#include "morph/worker_pool.h"

// A target cloud made ready for the morph: read at every n-th point when it is far denser than
// the template, then stray points and detached clutter taken out.
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
  /// A floor, a wall or a backdrop the scan took in, apart from the body: a piece whose
  /// points spread across their best plane at most `flat_thickness` of their spread along its
  /// second axis (standard deviations), at least `flat_width` of the body's diagonal wide
  /// (that second deviation times sqrt(12), a uniform sheet's width), with the body (the
  /// largest piece that is not flat) on one side of its plane (at most 1 % of the body's
  /// points beyond three of the plane's deviations on the other), and with at least half its
  /// points farther than the link radius from the body's shadow on its plane (a floor reaches
  /// out around the body; the face of a split carcass, or a floor cropped to the carcass's
  /// outline, lies under it and stays). Such a piece goes whatever its size and is never taken
  /// for the body, unless two such pieces lie in parallel planes apart: rows of a line scanner
  /// the neighbour graph could not join, and none goes. A flat part joined to the body is in
  /// the body's piece (touching_planes). 0 turns this rule and touching_planes off.
  double flat_thickness = 0.1;
  double flat_width = 0.25;
  /// A floor or wall the body touches, in one piece with it: at most this many planes found
  /// among the points before the pieces (one apart from the body too) and taken out when they
  /// are thin and wide (flat_thickness, flat_width), have the body on one side standing off
  /// them (its 90th percentile distance at least 0.05 of its diagonal: not the cut face of a
  /// split carcass seen alone), reach out of its shadow and its convex hull (not that cut
  /// face with its rim round it), are a sheet (not limbs spread flat in
  /// one plane) and reach round the centre of its shadow (a flat flap of the body lies
  /// beside it). The body's touching cap goes with them where it joins, and so does a thin
  /// limb lying on them. The band is three deviations of the plane's points (read from their
  /// median distance), at least two spacings and at most the link limit. 0: off.
  int touching_planes = 3;
  /// A cloud of more points than this many per template vertex is read at every n-th point
  /// (in its column order), the smallest n that brings it within the cap; 0: never. The
  /// surface morph resolves no finer than the template's vertices, and the morph's time grows
  /// faster than the points. Counted against the whole template, so a cloud that shows part
  /// of the body is thinned as if it showed all of it.
  double max_points_per_vertex = 8.0;
  /// When small far pieces were dropped, MorphCarcass also morphs with them put back (a limb a
  /// camera shadow cut off from the body lies apart as a hook does) and keeps that morph when
  /// its check gives it some confidence and reads no worse on every sign (docs/decisions.md);
  /// false: they stay out.
  bool rejoin_detached = true;
};

/// What the cleaning took out.
struct CleaningSummary {
  int strays = 0;          ///< points dropped as strays
  int detached = 0;        ///< points dropped in small far pieces of 2 or more
  int pieces_dropped = 0;  ///< how many such pieces
  int flat = 0;  ///< points dropped as floors, walls, backdrops (a touching plane's cap too)
  int flat_pieces = 0;     ///< how many such pieces
  int rejoined = 0;        ///< points of small far pieces put back (MorphCarcass)
  int rejoined_pieces = 0;          ///< how many such pieces
  int tried_back = 0;               ///< points of small far pieces tried back, put back or not
  double tried_back_seconds = 0.0;  ///< the second morph that tried them
  double spacing = 0.0;    ///< the cloud's median spacing as read, its units (0: not read)
  int stride = 1;          ///< every stride-th point of the input was read (max_points_per_vertex)
  double seconds = 0.0;
};

/// How many points the cleaning took out in all.
inline int Removed(const CleaningSummary& s) { return s.strays + s.detached + s.flat; }

/// The cloud with its clutter taken out.
struct CleanedTarget {
  Eigen::Matrix3Xd points;   ///< the kept points, in their input order
  Eigen::Matrix3Xd normals;  ///< theirs, when normals were given (else empty)
  std::vector<int> kept;     ///< input column of each kept point
  /// Input columns of the points in the small far pieces dropped (summary.detached of them;
  /// lone points dropped so are strays, not here), ascending.
  std::vector<int> detached;
  CleaningSummary summary;
};

/// Takes stray points, flat background pieces and small detached pieces out of @p points (3 by
/// N, any units), after reading every n-th of them when there are more than
/// options.max_points_per_vertex times @p template_vertices. @p normals is 3 by N or empty. Clouds
/// of fewer than 2 (neighbours + 1) points (after the thinning), or with cleaning off, are not
/// cleaned; clouds with a non-finite coordinate come back whole, for the stages to name the fault.
/// @param[out] index when given, the cloud was not thinned and nothing was taken out, receives
///   the kd-tree the cleaning built over @p points (which must then outlive it), for the
///   stages to reuse; else null.
/// @param pool when given, the neighbour search shares its threads (same result).
/// @param template_vertices the vertices of the template the cloud is for; 0: no thinning.
CleanedTarget CleanTarget(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                          const CleaningOptions& options = {},
                          std::unique_ptr<PointIndex>* index = nullptr, WorkerPool* pool = nullptr,
                          Eigen::Index template_vertices = 0);

}  // namespace vb::morph
