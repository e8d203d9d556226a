#pragma once

#include <span>
#include <vector>

#include "geometry/plane.h"
#include "geometry/surface_point.h"
#include "geometry/triangle_mesh.h"

namespace vb::geometry {

/// One connected piece of the intersection of a mesh with a plane. Each point lies on a mesh
/// edge and is given in the face the loop enters next, so it moves with the mesh.
struct SectionLoop {
  std::vector<SurfacePoint> points;
  bool closed = false;
};

/// Intersects @p mesh with @p plane. Vertices exactly on the plane count as on its positive
/// side, so every crossing lies strictly inside an edge. On a closed, consistently oriented
/// mesh every loop is closed, and all loops run the same way round the plane normal.
std::vector<SectionLoop> PlaneSection(const TriangleMesh& mesh, const Plane& plane);

/// Volume and outer surface area of one part of a cut mesh.
struct PartMeasure {
  double volume = 0.0;
  double area = 0.0;  ///< area of the mesh surface in the part, not counting the cut faces
};

/// Virtual cutting: splits a closed, outward-oriented mesh by the ordered @p cuts into
/// cuts.size() + 1 parts. Part 0 lies on the positive side of cut 0; part k (0 < k < n) on
/// the negative side of cut k-1 and the positive side of cut k; part n on the negative side
/// of the last cut. Each cut normal therefore points towards the parts before it. The parts'
/// volumes sum to the mesh volume whenever consecutive cuts do not cross inside the mesh.
std::vector<PartMeasure> MeasureParts(const TriangleMesh& mesh, std::span<const Plane> cuts);

}  // namespace vb::geometry
