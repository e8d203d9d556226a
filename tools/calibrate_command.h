#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace vb::tools {

struct CamerasCommandOptions {
  std::filesystem::path rig_path;    ///< optional: which rig entry each device is
  std::filesystem::path scene_path;  ///< optional: the virtual rig's scene
  std::vector<std::string> uris;     ///< also opened by URI (recordings, which are not listed)
};
/// `vbutcher cameras`: every OpenNI2 device (URI, vendor, name, serial, USB ids, depth and
/// colour modes) and the rig entry it matches (by serial or URI). A rig entry no listed
/// device matches is opened by its URI (an .oni recording) and checked against its
/// calibration: resolution, a depth format capture reads, focal lengths against the field of
/// view. Each of @p uris is opened the same way and printed with a rig entry to start from.
/// @return 0, or 3 when a rig entry or a URI cannot be opened or does not match.
int RunCameras(const CamerasCommandOptions& options);

struct TargetCommandOptions {
  std::filesystem::path target_path;  ///< optional; default: DefaultCalibrationTarget()
  std::filesystem::path out_yaml;     ///< writes the target's description
  std::filesystem::path out_mesh;     ///< writes its mesh (PLY, OFF or OBJ), for drawings or a scene
  double yaw_deg = 0;                 ///< the mesh turned about the rod
};
/// `vbutcher calibrate target`.
int RunCalibrateTarget(const TargetCommandOptions& options);

struct CalibrateCaptureOptions {
  std::filesystem::path rig_path;
  std::filesystem::path scene_path;
  std::filesystem::path out_dir;  ///< SERIAL.ply per camera: averaged points, camera frame
  int frames = 10;
  double timeout_s = 10;
};
/// `vbutcher calibrate capture`: one still view of whatever hangs on the hook, per camera.
int RunCalibrateCapture(const CalibrateCaptureOptions& options);

struct CalibrateRigOptions {
  std::filesystem::path rig_path;  ///< starting rig: names, serials, intrinsics, rough poses
  std::vector<std::filesystem::path> captures;  ///< one folder per target position, first = rig frame
  std::filesystem::path target_path;
  std::filesystem::path out_path;  ///< the calibrated rig (vbutcher-rig YAML)
  double max_rms_mm = 1.5;         ///< a camera's residual above this fails the calibration
};
/// `vbutcher calibrate rig`: finds the target's spheres in every capture, solves every
/// X_RigCam jointly, prints residuals per camera and writes the rig.
/// @return 0; 3 when a camera's residual is over max_rms_mm (the rig is still written, with
///   .rejected appended to its name).
int RunCalibrateRig(const CalibrateRigOptions& options);

struct CalibrateSawOptions {
  std::filesystem::path rig_path;     ///< the calibrated rig
  std::filesystem::path points_path;  ///< vbutcher-saw-points YAML
  std::filesystem::path out_path;     ///< X_SawRig as YAML, to paste into the daemon's config
  /// Instead of solving: the X_SawRig in this file (a daemon config or an earlier --out) is
  /// checked against the points.
  std::filesystem::path check_path;
  double max_rms_mm = 2.0;
};
/// `vbutcher calibrate saw`.
int RunCalibrateSaw(const CalibrateSawOptions& options);

struct CheckRigOptions {
  std::filesystem::path rig_path;
  std::filesystem::path scene_path;
  std::filesystem::path target_path;
  int frames = 10;
  double max_offset_mm = 2.5;
  double max_turn_deg = 0.5;
};
/// `vbutcher check-rig`: with the target on the hook, each camera against the others.
/// @return 0 when every camera agrees, 3 when one moved or fewer than 2 could be compared.
int RunCheckRig(const CheckRigOptions& options);

}  // namespace vb::tools
