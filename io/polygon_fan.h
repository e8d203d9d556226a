#pragma once

#include <Eigen/Core>
#include <span>
#include <vector>

namespace vb::io::internal {

/// Appends the fan triangulation (p0, p[i], p[i+1]) of a convex-enough polygon to @p indices
/// (three ints per triangle). @pre polygon.size() >= 3.
void AppendFan(std::span<const int> polygon, std::vector<int>* indices);

/// Packs a flat triangle index list into a 3 by #F matrix.
Eigen::Matrix3Xi FacesFromFlat(const std::vector<int>& indices);

}  // namespace vb::io::internal
