#include "perception/depth_renderer.h"

#include <algorithm>
#include <cmath>

namespace vb::perception {

DepthRenderer::DepthRenderer(const Intrinsics& intrinsics, const Eigen::Isometry3d& X_RigCam)
    : intrinsics_(intrinsics),
      X_RigCam_(X_RigCam),
      depth_m_(static_cast<std::size_t>(intrinsics.width) * intrinsics.height, 0.0f),
      cos_incidence_(depth_m_.size(), 0.0f) {}

void DepthRenderer::Render(const geometry::TriangleMesh& mesh_Rig,
                           std::optional<double> floor_z_m) {
  const Intrinsics& k = intrinsics_;
  const int w = k.width, h = k.height;
  std::fill(depth_m_.begin(), depth_m_.end(), 0.0f);
  std::fill(cos_incidence_.begin(), cos_incidence_.end(), 0.0f);
  const Eigen::Isometry3d X_CamRig = X_RigCam_.inverse();
  if (p_CamV_.cols() < mesh_Rig.V.cols()) p_CamV_.resize(3, mesh_Rig.V.cols());
  for (int i = 0; i < mesh_Rig.num_vertices(); ++i) p_CamV_.col(i) = X_CamRig * mesh_Rig.V.col(i);

  constexpr double kNear = 0.05;  // m; triangles crossing this plane are skipped
  for (int f = 0; f < mesh_Rig.num_faces(); ++f) {
    const Eigen::Vector3d a = p_CamV_.col(mesh_Rig.F(0, f));
    const Eigen::Vector3d b = p_CamV_.col(mesh_Rig.F(1, f));
    const Eigen::Vector3d c = p_CamV_.col(mesh_Rig.F(2, f));
    if (a.z() < kNear || b.z() < kNear || c.z() < kNear) continue;
    // Screen positions; 1/z is affine in screen space, so it is what we interpolate.
    const double ax = k.fx * a.x() / a.z() + k.cx, ay = k.fy * a.y() / a.z() + k.cy;
    const double bx = k.fx * b.x() / b.z() + k.cx, by = k.fy * b.y() / b.z() + k.cy;
    const double cx = k.fx * c.x() / c.z() + k.cx, cy = k.fy * c.y() / c.z() + k.cy;
    const double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    if (std::abs(area) < 1e-12) continue;
    const Eigen::Vector3d normal = (b - a).cross(c - a).normalized();
    const int u0 = std::max(0, static_cast<int>(std::floor(std::min({ax, bx, cx}))));
    const int u1 = std::min(w - 1, static_cast<int>(std::ceil(std::max({ax, bx, cx}))));
    const int v0 = std::max(0, static_cast<int>(std::floor(std::min({ay, by, cy}))));
    const int v1 = std::min(h - 1, static_cast<int>(std::ceil(std::max({ay, by, cy}))));
    const double inv_area = 1.0 / area;
    for (int v = v0; v <= v1; ++v) {
      for (int u = u0; u <= u1; ++u) {
        const double px = u, py = v;  // pixel centres at integer coordinates, as cx, cy
        const double wa = ((bx - px) * (cy - py) - (by - py) * (cx - px)) * inv_area;
        const double wb = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) * inv_area;
        const double wc = 1.0 - wa - wb;
        if (wa < 0 || wb < 0 || wc < 0) continue;
        const double z = 1.0 / (wa / a.z() + wb / b.z() + wc / c.z());
        const std::size_t i = static_cast<std::size_t>(v) * w + u;
        if (depth_m_[i] != 0.0f && depth_m_[i] <= z) continue;
        const Eigen::Vector3d ray((px - k.cx) / k.fx, (py - k.cy) / k.fy, 1.0);
        depth_m_[i] = static_cast<float>(z);
        cos_incidence_[i] = static_cast<float>(std::abs(normal.dot(ray.normalized())));
      }
    }
  }
  if (!floor_z_m) return;
  // The floor where nothing nearer was hit: ray (d_C, with d_C.z = 1) meets z_Rig = floor.
  const Eigen::Matrix3d R = X_RigCam_.linear();
  const double t_z = X_RigCam_.translation().z();
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * w + u;
      if (depth_m_[i] != 0.0f) continue;
      const Eigen::Vector3d d_C((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      const double dz = R.row(2).dot(d_C);
      if (std::abs(dz) < 1e-9) continue;
      const double depth = (*floor_z_m - t_z) / dz;
      if (depth <= kNear) continue;
      depth_m_[i] = static_cast<float>(depth);
      cos_incidence_[i] = static_cast<float>(std::abs(dz) / d_C.norm());
    }
  }
}

}  // namespace vb::perception
