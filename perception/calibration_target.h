#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

#include "geometry/triangle_mesh.h"

namespace vb::perception {

/// One sphere of the calibration target.
struct TargetSphere {
  Eigen::Vector3d centre_T = Eigen::Vector3d::Zero();  ///< target frame (m)
  double radius_m = 0.1;
};

/// What is hung on the hook to calibrate the rig from depth alone: spheres of different
/// known radii on a vertical rod, some on horizontal arms. Spheres look the same from every
/// side, so every camera measures the same centres; their radii tell them apart. The target
/// frame T: origin at the hook, z up along the rod, x towards the first sphere off the rod.
/// Hung in its first position it defines the rig frame. File format "vbutcher-target"
/// version 1 (YAML):
/// ```
/// format: vbutcher-target
/// version: 1
/// name: vb-spheres-3
/// rod_radius_m: 0.012
/// spheres:
///   - {centre: [0, 0, -0.3], radius_m: 0.1}     # target frame, metres
/// ```
struct CalibrationTarget {
  static constexpr int kFormatVersion = 1;
  static constexpr int kMaxSpheres = 8;
  /// Radii must differ by this much: the radius a camera fits names the sphere.
  static constexpr double kMinRadiusGapM = 0.015;
  std::string name = "vb-spheres-3";
  std::vector<TargetSphere> spheres;
  double rod_radius_m = 0.012;  ///< the rod and the arms (drawn and rendered, not fitted)
};

/// The target this project ships drawings for: 3 spheres of 100, 80 and 60 mm radius at
/// 0.30 m and 1.00 m below the hook on the rod and 0.30 m out on an arm 0.55 m below it.
/// Pairwise centre distances 0.70, 0.36 and 0.58 m.
CalibrationTarget DefaultCalibrationTarget();

/// Checks a target can calibrate: 3 to kMaxSpheres spheres, radii from 0.03 to 0.3 m and
/// kMinRadiusGapM apart, spheres apart, centres not on one line, within 0.6 m of the rod
/// and 1.8 m below the hook. @return the problems, empty when usable.
std::vector<std::string> CheckCalibrationTarget(const CalibrationTarget& target);

/// @throws InputError "file:line: key: problem", or listing CheckCalibrationTarget's problems.
CalibrationTarget LoadCalibrationTarget(const std::filesystem::path& path);
/// @throws std::runtime_error when the file cannot be written.
void SaveCalibrationTarget(const std::filesystem::path& path, const CalibrationTarget& target);

/// The target as a triangle mesh posed at @p X_RigTarget: spheres (subdivided icosahedra,
/// within 0.1 mm of the true sphere), the rod from the hook to the lowest sphere and an arm
/// to each sphere off the rod. For the virtual rig's scene and as a drawing to build from.
geometry::TriangleMesh TargetMesh(
    const CalibrationTarget& target,
    const Eigen::Isometry3d& X_RigTarget = Eigen::Isometry3d::Identity());

}  // namespace vb::perception
