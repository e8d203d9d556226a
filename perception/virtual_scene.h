#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "perception/depth_noise.h"
#include "perception/rig_calibration.h"

namespace vb::perception {

/// A fault the virtual rig can put on one of its cameras, on demand.
enum class CameraFault {
  kNone,
  kFrozen,   ///< keeps delivering the same image
  kMissing,  ///< delivers nothing and cannot be opened again while the fault lasts
};

/// What the virtual OpenNI2 driver renders: the rig, the carcass hanging in it, the sensor
/// model and the faults. The driver reads the file named by $VB_VIRTUAL_SCENE at start and
/// again whenever it changes, so a test or the demo swaps carcasses and injects faults by
/// rewriting it. Format "vbutcher-virtual-scene" version 1 (YAML):
/// ```
/// format: vbutcher-virtual-scene
/// version: 1
/// rig: rig.yaml            # calibration (relative paths are from this file's folder)
/// carcass: carcass.ply     # mesh in the rig frame; optional (an empty hook)
/// fps: 30
/// start_delay_ms: 0        # optional: a stream's first frame comes this much later (ms)
/// start_delays_ms: {VB0002: 2500}  # optional, per serial: replaces start_delay_ms for it
/// floor_z_m: -2.2          # optional floor plane
/// noise: {enabled: true, seed: 1}
/// faults: {VB0002: frozen} # per serial: none | frozen | missing
/// ```
struct VirtualScene {
  static constexpr int kFormatVersion = 1;
  RigCalibration rig;
  std::filesystem::path rig_path;
  std::filesystem::path carcass_path;  ///< empty: nothing on the hook
  int fps = 30;
  int start_delay_ms = 0;  ///< ms from a stream's start to one frame period before its first frame
  std::map<std::string, int> start_delays_ms;  ///< by serial, in place of start_delay_ms
  std::optional<double> floor_z_m;
  DepthNoiseOptions noise;
  std::uint64_t seed = 1;
  std::map<std::string, CameraFault> faults;  ///< by serial

  CameraFault fault(const std::string& serial) const;
  /// The start delay of the camera with @p serial (ms).
  int start_delay(const std::string& serial) const;
};

/// @throws InputError naming file, line, key and value for anything wrong, including faults
///   for serials the rig does not have.
VirtualScene LoadVirtualScene(const std::filesystem::path& path);

/// Writes a scene file; @p rig_path and @p carcass_path are written as given.
void SaveVirtualScene(const std::filesystem::path& path, const VirtualScene& scene);

const char* ToString(CameraFault fault);

}  // namespace vb::perception
