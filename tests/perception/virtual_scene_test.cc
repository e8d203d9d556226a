#include "perception/virtual_scene.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/error.h"
#include "perception/rig_calibration.h"
#include "tests/support/temp_dir.h"

namespace vb::perception {
namespace {

using ::testing::HasSubstr;

class VirtualSceneTest : public ::testing::Test {
 protected:
  void SetUp() override { SaveRigCalibration(dir_ / "rig.yaml", MakeRingRig({})); }
  std::string Error(const std::string& body) {
    const auto path = dir_.Write("scene.yaml", "format: vbutcher-virtual-scene\nversion: 1\n" + body);
    try {
      LoadVirtualScene(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "(accepted)";
  }
  test::TempDir dir_;
};

TEST_F(VirtualSceneTest, RoundTrips) {
  VirtualScene scene;
  scene.rig_path = "rig.yaml";
  scene.fps = 15;
  scene.start_delay_ms = 450;
  scene.start_delays_ms["VB0002"] = 2500;
  scene.floor_z_m = -2.0;
  scene.seed = 9;
  scene.noise.enabled = false;
  scene.faults["VB0003"] = CameraFault::kFrozen;
  SaveVirtualScene(dir_ / "scene.yaml", scene);
  const VirtualScene back = LoadVirtualScene(dir_ / "scene.yaml");
  EXPECT_EQ(back.rig.cameras.size(), 4u);
  EXPECT_EQ(back.fps, 15);
  EXPECT_EQ(back.start_delay_ms, 450);
  EXPECT_EQ(back.start_delay("VB0002"), 2500);
  EXPECT_EQ(back.start_delay("VB0001"), 450);
  EXPECT_EQ(*back.floor_z_m, -2.0);
  EXPECT_EQ(back.seed, 9u);
  EXPECT_FALSE(back.noise.enabled);
  EXPECT_EQ(back.fault("VB0003"), CameraFault::kFrozen);
  EXPECT_EQ(back.fault("VB0001"), CameraFault::kNone);
  EXPECT_TRUE(back.carcass_path.empty());
}

TEST_F(VirtualSceneTest, NamesWhatIsWrong) {
  EXPECT_THAT(Error("rig: rig.yaml\nfaults: {VB0009: frozen}\n"),
              HasSubstr("faults.VB0009: the rig has no camera with serial 'VB0009'"));
  EXPECT_THAT(Error("rig: rig.yaml\nfaults: {VB0001: melted}\n"),
              HasSubstr("faults.VB0001: 'melted' is not one of none, frozen, missing"));
  EXPECT_THAT(Error("rig: rig.yaml\ncarcass: nowhere.ply\n"), HasSubstr("carcass: no file"));
  EXPECT_THAT(Error("rig: rig.yaml\nfps: 0\n"), HasSubstr("fps: value 0 is outside [1, 120]"));
  EXPECT_THAT(Error("rig: rig.yaml\nstart_delay_ms: -1\n"),
              HasSubstr("start_delay_ms: value -1 is outside [0, 10000]"));
  EXPECT_THAT(Error("rig: rig.yaml\nstart_delays_ms: {VB0009: 100}\n"),
              HasSubstr("start_delays_ms.VB0009: the rig has no camera with serial 'VB0009'"));
  EXPECT_THAT(Error("rig: rig.yaml\nstart_delays_ms: {VB0001: 20000}\n"),
              HasSubstr("start_delays_ms.VB0001: value 20000 is outside [0, 10000]"));
  EXPECT_THAT(Error("rig: rig.yaml\nstart_delays_ms: 100\n"),
              HasSubstr("start_delays_ms: expected a mapping of serial: ms"));
  EXPECT_THAT(Error("rig: rig.yaml\nstart_delays_ms: {[VB0001, VB0002]: 100}\n"),
              HasSubstr("start_delays_ms key: expected a single value"));
  EXPECT_THAT(Error("rig: rig.yaml\nfaults: {{VB0001: 1}: frozen}\n"),
              HasSubstr("faults key: expected a single value"));
  EXPECT_THAT(Error("rig: other.yaml\n"), HasSubstr("other.yaml: cannot open rig calibration file"));
}

}  // namespace
}  // namespace vb::perception
