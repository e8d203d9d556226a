#include "io/polygon_fan.h"

#include "io/error.h"

namespace vb::io::internal {

void AppendFan(std::span<const int> polygon, std::vector<int>* indices) {
  VB_DEMAND(polygon.size() >= 3);
  for (std::size_t i = 1; i + 1 < polygon.size(); ++i) {
    indices->push_back(polygon[0]);
    indices->push_back(polygon[i]);
    indices->push_back(polygon[i + 1]);
  }
}

Eigen::Matrix3Xi FacesFromFlat(const std::vector<int>& indices) {
  VB_DEMAND(indices.size() % 3 == 0);
  Eigen::Matrix3Xi F(3, static_cast<Eigen::Index>(indices.size() / 3));
  for (Eigen::Index f = 0; f < F.cols(); ++f) {
    for (int k = 0; k < 3; ++k) F(k, f) = indices[static_cast<std::size_t>(3 * f + k)];
  }
  return F;
}

}  // namespace vb::io::internal
