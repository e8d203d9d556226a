#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

namespace vb::perception {

/// Pinhole intrinsics of a depth image (pixels). Pixel (u, v) with depth z (m) is the point
/// ((u - cx) z / fx, (v - cy) z / fy, z) in the camera's optical frame C (x right, y down,
/// z forward).
struct Intrinsics {
  int width = 640;
  int height = 480;
  double fx = 570.3;
  double fy = 570.3;
  double cx = 319.5;
  double cy = 239.5;
};

/// One depth camera of the rig.
struct CameraCalibration {
  std::string name;    ///< operator-facing, e.g. "front_left"
  std::string serial;  ///< the device's serial number; also how the camera is found
  /// OpenNI2 URI to open ("vbrig://SERIAL" for the virtual rig, a .oni file for playback); when
  /// empty the device whose serial matches is opened.
  std::string uri;
  Intrinsics intrinsics;
  /// Pose of the camera's optical frame C in the rig frame (metres).
  Eigen::Isometry3d X_RigCam = Eigen::Isometry3d::Identity();
};

/// The calibrated rig: cameras around the hook, all in one rig frame (z up, origin at the
/// hook). File format "vbutcher-rig" version 1 (YAML):
/// ```
/// format: vbutcher-rig
/// version: 1
/// rig: line3_primal
/// cameras:
///   - name: front
///     serial: VB0001
///     uri: vbrig://VB0001          # optional
///     resolution: [640, 480]
///     intrinsics: {fx: 570.3, fy: 570.3, cx: 319.5, cy: 239.5}
///     X_RigCam:
///       translation: [1.0, 0.0, -0.55]            # metres
///       rotation_wxyz: [0.5, -0.5, 0.5, -0.5]     # unit quaternion (normalised if within 1e-3)
/// ```
struct RigCalibration {
  static constexpr int kFormatVersion = 1;
  static constexpr int kMaxCameras = 16;
  std::string rig_name;
  std::vector<CameraCalibration> cameras;
};

/// Loads and validates a rig calibration.
/// @throws InputError "file:line: key: problem" for a missing key, a bad value (non-finite,
///   a non-positive focal length, a principal point outside the image, a rotation that is not
///   a unit quaternion), an unknown format or version, or repeated names or serials.
RigCalibration LoadRigCalibration(const std::filesystem::path& path);

/// Writes @p rig in the format above with round-trip precision.
/// @throws std::runtime_error when the file cannot be written.
void SaveRigCalibration(const std::filesystem::path& path, const RigCalibration& rig);

/// Options of a ring of cameras around the hook, looking at the carcass. The defaults see a
/// whole hanging lamb (up to 1.4 m): a VGA PrimeSense camera in landscape sees only 0.84 m
/// of height at 1 m (45 degrees vertical field of view), which leaves out the hind legs and
/// the neck, and the morph then fails; turned to portrait at 1.2 m it sees 1.33 m.
struct RingRigOptions {
  int num_cameras = 4;
  /// Horizontal distance from the hanging axis. A portrait PrimeSense sees 2 tan(29.3 deg)
  /// = 1.12 m of height per metre of range; at 1.6 m the near side of a carcass (about
  /// 1.4 m away) shows 1.57 m, the largest lamb (1.44 m below the hook) with margin. At
  /// 1.2 m the bottom 0.1-0.15 m of the largest carcasses fell outside the view and their
  /// cut planes were 20-50 mm off (bench-daemon).
  double radius_m = 1.6;
  double height_m = -0.72;       ///< camera height in the rig frame (hook at 0, z up)
  double look_at_z_m = -0.72;    ///< height of the point on the axis the cameras look at
  bool portrait = true;          ///< image columns along the vertical
  double first_azimuth_deg = 0;  ///< azimuth of camera 0 about +z
  Intrinsics intrinsics;
  std::string serial_prefix = "VB";
  std::string uri_scheme = "vbrig://";  ///< URIs are scheme + serial; empty for none
};

/// A ring of cameras evenly spread in azimuth, each looking at the hanging axis.
RigCalibration MakeRingRig(const RingRigOptions& options);

/// X_RigCam for a camera at @p p_RigCam looking at @p p_RigTarget, image "up" towards +z, or
/// with @p portrait image "left" towards +z (the camera turned a quarter about its axis).
Eigen::Isometry3d LookAt(const Eigen::Vector3d& p_RigCam, const Eigen::Vector3d& p_RigTarget,
                         bool portrait = false);

}  // namespace vb::perception
