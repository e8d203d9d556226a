#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "perception/oni_recording.h"
#include "perception/rig_calibration.h"

namespace vb::tools {

/// Points the virtual rig's OpenNI2 driver at @p scene ($VB_VIRTUAL_SCENE) after loading it,
/// so a bad file is refused with its message; nothing when @p scene is empty.
/// @throws InputError for a bad scene file.
void UseScene(const std::filesystem::path& scene);

struct VirtualRigCommandOptions {
  std::filesystem::path out_dir;
  int cameras = 4;
  double radius_m = perception::RingRigOptions{}.radius_m;
  std::uint64_t seed = 1;  ///< carcass pose
  bool no_noise = false;
  int fps = 30;
};
/// `vbutcher virtual-rig`: writes a virtual rig (calibration, hanging carcass, scene file).
int RunVirtualRig(const VirtualRigCommandOptions& options);

struct CaptureCommandOptions {
  std::filesystem::path rig_path;
  std::filesystem::path scene_path;  ///< optional: sets $VB_VIRTUAL_SCENE for the virtual rig
  std::filesystem::path out_path;    ///< fused cloud (.ply, .pcd, .xyz)
  double timeout_s = 5.0;
  double voxel_mm = 6.0;
  int max_points = 60000;
};
/// `vbutcher capture`: one frame set from the rig, fused, written as a cloud with normals.
int RunCapture(const CaptureCommandOptions& options);

struct RecordCommandOptions {
  std::filesystem::path rig_path;
  std::filesystem::path scene_path;
  perception::RecordOptions record;  ///< out_dir, seconds and grace_seconds
};
/// `vbutcher record`: one .oni per camera plus a playback calibration.
int RunRecord(const RecordCommandOptions& options);

struct VirtualLineOptions {
  std::filesystem::path scene_path;
  int count = 5;
  std::uint64_t first_seed = 100;
  double hang_s = 4.0;              ///< a carcass stays this long in the rig
  double gap_s = 1.0;               ///< then the hook is empty this long
  std::filesystem::path truth_out;  ///< per carcass its true cut planes (YAML)
};
/// `vbutcher virtual-line`: a stream of synthetic carcasses through a virtual scene.
int RunVirtualLine(const VirtualLineOptions& options);

struct CaptureBenchOptions {
  std::filesystem::path scene_path;  ///< empty: a 4-camera virtual rig in a temporary folder
  int sets = 300;                    ///< frame sets to capture and fuse
  int warmup_sets = 10;
  std::filesystem::path csv = "bench_capture.csv";
};
/// `vbutcher bench capture`: capture + fusion time per frame set and memory over the run.
int RunCaptureBench(const CaptureBenchOptions& options);

}  // namespace vb::tools
