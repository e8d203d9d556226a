#pragma once

#include <cstdint>
#include <filesystem>

#include "perception/carcass_generator.h"
#include "perception/rig_calibration.h"
#include "perception/virtual_scene.h"

namespace vb::perception {

/// Hangs a synthetic carcass (pose drawn from @p seed, upright; joint ranges times
/// @p angle_scale, PoseOptions::angle_scale) on the rig's hook: the gambrel end at z = 0, the
/// body centred on the z axis. Mesh, skeleton and true cut planes are all in the rig frame.
PosedCarcass HangCarcass(const CarcassTemplate& carcass, std::uint64_t seed,
                         double angle_scale = 1.0);

struct VirtualRigOptions {
  std::filesystem::path out_dir;
  RingRigOptions ring;
  std::uint64_t carcass_seed = 1;
  bool noise = true;
  int fps = 30;
  double floor_z_m = -2.2;
};

/// The files of a virtual rig with one carcass on the hook.
struct VirtualRigFiles {
  std::filesystem::path scene;    ///< point $VB_VIRTUAL_SCENE here
  std::filesystem::path rig;      ///< the calibration the capture side reads
  std::filesystem::path carcass;  ///< the hanging carcass mesh (rig frame)
  PosedCarcass truth;             ///< that carcass with its ground truth
};

/// Writes out_dir/{rig.yaml, carcass.ply, scene.yaml}.
VirtualRigFiles WriteVirtualRig(const CarcassTemplate& carcass, const VirtualRigOptions& options);

/// A line of carcasses through an existing virtual scene: hangs carcass k (its own file, so
/// the driver sees a change) or empties the hook, by rewriting the scene file.
class VirtualLine {
 public:
  /// @throws InputError when @p scene_path is not a valid scene.
  VirtualLine(const CarcassTemplate* carcass, std::filesystem::path scene_path);
  /// Hangs the carcass of pose seed @p seed; returns it with its ground truth (rig frame).
  PosedCarcass Hang(std::uint64_t seed);
  /// Nothing on the hook.
  void Clear();

 private:
  const CarcassTemplate* carcass_;
  std::filesystem::path scene_path_;
  VirtualScene scene_;
};

}  // namespace vb::perception
