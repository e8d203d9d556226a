#pragma once

#include <Eigen/Core>
#include <vector>

#include "geometry/triangle_mesh.h"

namespace vb::test {

/// A closed mesh of the union of capsules (segment a-b, radius r), by marching tetrahedra at
/// grid spacing @p h.
struct Capsule {
  Eigen::Vector3d a, b;
  double r;
};
geometry::TriangleMesh CapsuleUnion(const std::vector<Capsule>& capsules, double h);

/// Three arms of length 1 and radius 0.12 meeting at the origin (a "Y"), as a closed mesh.
geometry::TriangleMesh YShape(double h = 0.04);

}  // namespace vb::test
