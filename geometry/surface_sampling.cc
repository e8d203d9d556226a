#include "geometry/surface_sampling.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <stdexcept>
#include <vector>

namespace vb::geometry {

void SampleSurface(const TriangleMesh& surface, int count, const std::function<double()>& uniform,
                   Eigen::Matrix3Xd* points, Eigen::Matrix3Xd* normals) {
  std::vector<double> cumulative(static_cast<std::size_t>(surface.num_faces()));
  double total = 0;
  for (int f = 0; f < surface.num_faces(); ++f) {
    const Eigen::Vector3d a = surface.V.col(surface.F(0, f));
    total +=
        0.5 * (surface.V.col(surface.F(1, f)) - a).cross(surface.V.col(surface.F(2, f)) - a).norm();
    cumulative[static_cast<std::size_t>(f)] = total;
  }
  if (!(total > 0)) throw std::invalid_argument("the surface has no area");
  points->resize(3, count);
  normals->resize(3, count);
  for (int i = 0; i < count; ++i) {
    const double at = uniform() * total;
    const auto f = static_cast<int>(std::min<std::ptrdiff_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), at) - cumulative.begin(),
        surface.num_faces() - 1));
    double u = uniform();
    double v = uniform();
    if (u + v > 1) {
      u = 1 - u;
      v = 1 - v;
    }
    const Eigen::Vector3d a = surface.V.col(surface.F(0, f));
    const Eigen::Vector3d b = surface.V.col(surface.F(1, f));
    const Eigen::Vector3d c = surface.V.col(surface.F(2, f));
    points->col(i) = a + u * (b - a) + v * (c - a);
    normals->col(i) = (b - a).cross(c - a).normalized();
  }
}

}  // namespace vb::geometry
