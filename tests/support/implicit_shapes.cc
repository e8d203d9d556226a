#include "tests/support/implicit_shapes.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "perception/marching_tetrahedra.h"

namespace vb::test {

geometry::TriangleMesh CapsuleUnion(const std::vector<Capsule>& capsules, double h) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  for (const Capsule& c : capsules) {
    lo = lo.cwiseMin(c.a.cwiseMin(c.b) - Eigen::Vector3d::Constant(c.r + 2 * h));
    hi = hi.cwiseMax(c.a.cwiseMax(c.b) + Eigen::Vector3d::Constant(c.r + 2 * h));
  }
  const auto f = [&capsules](const Eigen::Vector3d& p) {
    double d = std::numeric_limits<double>::infinity();
    for (const Capsule& c : capsules) {
      const Eigen::Vector3d ab = c.b - c.a;
      const double t = std::clamp((p - c.a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
      d = std::min(d, (p - (c.a + t * ab)).norm() - c.r);
    }
    return d;
  };
  return perception::MarchingTetrahedra(f, lo, hi, h);
}

geometry::TriangleMesh YShape(double h) {
  std::vector<Capsule> arms;
  for (int k = 0; k < 3; ++k) {
    const double angle = 2.0 * M_PI * k / 3.0 + 0.3;
    arms.push_back({Eigen::Vector3d::Zero(),
                    Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.1 * k), 0.12});
  }
  return CapsuleUnion(arms, h);
}

}  // namespace vb::test
