#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>

#include "perception/carcass_generator.h"
#include "perception/virtual_rig.h"
#include "perception/virtual_scene.h"
#include "tests/support/temp_dir.h"

namespace vb::test {

/// A virtual OpenNI2 rig for one test: rig, hanging carcass and scene files in a temporary
/// folder, and $VB_VIRTUAL_SCENE pointing at them, so the real OpenNI2 path (our driver
/// plugin) serves the test's cameras. The carcass template is built once per suite.
class VirtualRigTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    carcass_ = std::make_unique<perception::CarcassTemplate>(perception::BuildCarcassTemplate());
  }
  static void TearDownTestSuite() { carcass_.reset(); }

  /// Writes the rig; call before the first capture is made (OpenNI2 reads it at start).
  void WriteRig(const perception::VirtualRigOptions& given = {}) {
    perception::VirtualRigOptions options = given;
    options.out_dir = dir_.path();
    files_ = perception::WriteVirtualRig(*carcass_, options);
    setenv("VB_VIRTUAL_SCENE", files_.scene.c_str(), 1);
    scene_ = perception::LoadVirtualScene(files_.scene);
  }

  /// Rewrites the scene with @p fault on camera @p serial (the driver notices within 50 ms).
  void SetFault(const std::string& serial, perception::CameraFault fault) {
    scene_.faults[serial] = fault;
    SaveScene();
  }

  /// Rewrites the scene so every stream started from now on gives its first frame @p ms later.
  void SetStartDelay(int ms) {
    scene_.start_delay_ms = ms;
    SaveScene();
  }

  /// As SetStartDelay, for the camera with @p serial alone.
  void SetStartDelay(const std::string& serial, int ms) {
    scene_.start_delays_ms[serial] = ms;
    SaveScene();
  }

  /// Writes scene_ as the driver's scene file, naming the rig and carcass beside it.
  void SaveScene() const {
    perception::VirtualScene scene = scene_;
    scene.rig_path = "rig.yaml";
    scene.carcass_path = "carcass.ply";
    perception::SaveVirtualScene(files_.scene, scene);
  }

  static inline std::unique_ptr<perception::CarcassTemplate> carcass_;
  TempDir dir_;
  perception::VirtualRigFiles files_;
  perception::VirtualScene scene_;
};

}  // namespace vb::test
