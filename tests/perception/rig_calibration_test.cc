#include "perception/rig_calibration.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::perception {
namespace {

using ::testing::HasSubstr;

TEST(RigCalibrationTest, RingCamerasLookAtTheHangingAxis) {
  RingRigOptions options;
  options.num_cameras = 3;
  const RigCalibration rig = MakeRingRig(options);
  ASSERT_EQ(rig.cameras.size(), 3u);
  for (const CameraCalibration& cam : rig.cameras) {
    const Eigen::Vector3d p = cam.X_RigCam.translation();
    EXPECT_NEAR(p.head<2>().norm(), options.radius_m, 1e-12);
    // The optical axis (z of C) points at the axis point; in portrait the image's columns
    // (x of C) run down the carcass, and its rows are horizontal.
    const Eigen::Vector3d to_target = (Eigen::Vector3d(0, 0, options.look_at_z_m) - p).normalized();
    EXPECT_NEAR(cam.X_RigCam.linear().col(2).dot(to_target), 1.0, 1e-12);
    EXPECT_NEAR(cam.X_RigCam.linear().col(0).z(), -1.0, 1e-12);
    EXPECT_NEAR(cam.X_RigCam.linear().col(1).z(), 0.0, 1e-12);
    EXPECT_NEAR(cam.X_RigCam.linear().determinant(), 1.0, 1e-12);
  }
  EXPECT_EQ(rig.cameras[1].uri, "vbrig://VB0002");
  options.portrait = false;  // landscape: image down is world down
  for (const CameraCalibration& cam : MakeRingRig(options).cameras)
    EXPECT_LT(cam.X_RigCam.linear().col(1).z(), -0.99);
}

TEST(RigCalibrationTest, RoundTripsThroughItsFile) {
  test::TempDir dir;
  const RigCalibration rig = MakeRingRig({});
  SaveRigCalibration(dir / "rig.yaml", rig);
  const RigCalibration back = LoadRigCalibration(dir / "rig.yaml");
  ASSERT_EQ(back.cameras.size(), rig.cameras.size());
  EXPECT_EQ(back.rig_name, rig.rig_name);
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    EXPECT_EQ(back.cameras[i].serial, rig.cameras[i].serial);
    EXPECT_EQ(back.cameras[i].uri, rig.cameras[i].uri);
    EXPECT_EQ(back.cameras[i].intrinsics.fx, rig.cameras[i].intrinsics.fx);
    EXPECT_TRUE(back.cameras[i].X_RigCam.isApprox(rig.cameras[i].X_RigCam, 1e-12));
  }
}

class BadRigTest : public ::testing::Test {
 protected:
  // A valid file, then one line replaced: each refusal must name the key and the value.
  void ExpectRejected(const std::string& from, const std::string& to, const std::string& what) {
    SaveRigCalibration(dir_ / "good.yaml", MakeRingRig({}));
    std::ifstream in(dir_ / "good.yaml");
    std::stringstream text;
    text << in.rdbuf();
    std::string s = text.str();
    // A `from` ending in '*' stands for the rest of its line.
    const bool to_eol = from.back() == '*';
    const std::string key = to_eol ? from.substr(0, from.size() - 1) : from;
    const std::size_t at = s.find(key);
    ASSERT_NE(at, std::string::npos) << from;
    s.replace(at, to_eol ? s.find('\n', at) - at : key.size(), to);
    const auto path = dir_.Write("bad.yaml", s);
    try {
      LoadRigCalibration(path);
      ADD_FAILURE() << "accepted: " << to;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("bad.yaml:")) << e.what();
      EXPECT_THAT(e.what(), HasSubstr(what)) << e.what();
    }
  }
  test::TempDir dir_;
};

TEST_F(BadRigTest, NamesTheKeyAndValue) {
  ExpectRejected("format: vbutcher-rig", "format: vbutcher-rag", "format: is 'vbutcher-rag'");
  ExpectRejected("version: 1", "version: 9", "version: 9 is not supported");
  ExpectRejected("fx: 570.29999999999995", "fx: -570", "cameras[0].intrinsics.fx: value -570");
  ExpectRejected("fy: 570.29999999999995", "fy: .nan", "cameras[0].intrinsics.fy: value '.nan' is not finite");
  ExpectRejected("cx: 319.5", "cx: 700", "cameras[0].intrinsics.cx: value 700 is outside");
  ExpectRejected("resolution: [640, 480]", "resolution: [640]", "cameras[0].resolution: expected [width, height]");
  ExpectRejected("serial: VB0002", "serial: VB0001", "cameras[1].serial: 'VB0001' is empty or repeated");
  ExpectRejected("name: cam1", "name: cam0", "cameras[1].name: 'cam0' is empty or repeated");
  ExpectRejected("rotation_wxyz: *", "rotation_wxyz: [1, 1, 0, 0]", "rotation_wxyz: is not a unit quaternion");
  ExpectRejected("translation: *", "translation: [abc, 0, 0]", "X_RigCam.translation[0]: cannot read 'abc'");
  ExpectRejected("    intrinsics:", "    intrinsicz:", "cameras[0].intrinsics: missing");
}

TEST(RigCalibrationTest, ShippedExampleIsARealCameraRigAsTheVirtualRingPlacesIt) {
  // The package installs it as the plant's rig.yaml: found by serial, no virtual URIs, and
  // the same nominal poses as the virtual ring the demo runs on (within 1 um, 1e-6 rad).
  const RigCalibration rig = LoadRigCalibration(VB_SOURCE_DIR "/config/rig.yaml");
  const RigCalibration ring = MakeRingRig({});
  ASSERT_EQ(rig.cameras.size(), ring.cameras.size());
  for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
    EXPECT_TRUE(rig.cameras[c].uri.empty()) << rig.cameras[c].name;
    EXPECT_LT((rig.cameras[c].X_RigCam.translation() - ring.cameras[c].X_RigCam.translation())
                  .norm(),
              1e-6);
    EXPECT_LT(Eigen::AngleAxisd(rig.cameras[c].X_RigCam.linear().transpose() *
                                ring.cameras[c].X_RigCam.linear())
                  .angle(),
              1e-6);
  }
}

TEST(RigCalibrationTest, RefusesEmptyRigsAndMissingFiles) {
  test::TempDir dir;
  const auto empty =
      dir.Write("empty.yaml", "format: vbutcher-rig\nversion: 1\nrig: x\ncameras: []\n");
  EXPECT_THROW(LoadRigCalibration(empty), InputError);
  EXPECT_THROW(LoadRigCalibration(dir / "absent.yaml"), InputError);
}

}  // namespace
}  // namespace vb::perception
