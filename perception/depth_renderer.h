#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

#include "geometry/triangle_mesh.h"
#include "perception/rig_calibration.h"

namespace vb::perception {

/// Renders the noise-free depth image one camera of the rig would see of a triangle mesh
/// (software z-buffer, perspective-correct depth), optionally with a floor plane behind it.
/// Owns its image buffers, sized once from the intrinsics: Render() allocates nothing.
/// Not thread safe: one renderer per camera.
class DepthRenderer {
 public:
  DepthRenderer(const Intrinsics& intrinsics, const Eigen::Isometry3d& X_RigCam);

  /// Renders @p mesh_Rig (vertices in the rig frame). Pixels that see nothing get depth 0.
  /// @param floor_z_m  when set, the horizontal plane z = floor_z_m of the rig frame is seen
  ///   where the mesh is not (a slaughter-hall floor).
  void Render(const geometry::TriangleMesh& mesh_Rig,
              std::optional<double> floor_z_m = std::nullopt);

  /// Row-major #height x #width depth along the optical axis (m), 0 where nothing was hit.
  const std::vector<float>& depth_m() const { return depth_m_; }
  /// Cosine of the angle between the viewing ray and the surface normal, per pixel (0 where
  /// nothing was hit): small values are grazing views.
  const std::vector<float>& cos_incidence() const { return cos_incidence_; }
  const Intrinsics& intrinsics() const { return intrinsics_; }
  const Eigen::Isometry3d& X_RigCam() const { return X_RigCam_; }

 private:
  Intrinsics intrinsics_;
  Eigen::Isometry3d X_RigCam_;
  std::vector<float> depth_m_;
  std::vector<float> cos_incidence_;
  Eigen::Matrix3Xd p_CamV_;  // vertices in the camera frame; resized only when #V grows
};

}  // namespace vb::perception
