#include "perception/oni_recording.h"

#include <gtest/gtest.h>

#include "perception/depth_noise.h"
#include "perception/depth_renderer.h"
#include "tests/support/virtual_rig_fixture.h"

namespace vb::perception {
namespace {

using OniRecordingTest = test::VirtualRigTest;

TEST_F(OniRecordingTest, RecordingPlaysBackThroughOpenNi2sFileDriver) {
  perception::VirtualRigOptions options;
  options.ring.num_cameras = 2;
  options.noise = false;  // so the played image can be compared with a fresh render
  WriteRig(options);
  RecordOptions record;
  record.out_dir = dir_ / "recording";
  record.seconds = 1.0;
  // A noise-free static scene repeats its image exactly, which capture rightly calls frozen;
  // keep its recovery (a stream restart) out of this recording.
  CaptureOptions capture;
  capture.recovery_period_ms = 60000;
  const RecordSummary summary = RecordOni(scene_.rig, capture, record);
  ASSERT_EQ(summary.files.size(), 2u);
  EXPECT_GE(summary.frames_seen[0], 10u);  // 30 fps nominal; half under a sanitizer build
  EXPECT_TRUE(std::filesystem::file_size(summary.files[0]) > 100000);

  // Replay: the playback calibration's URIs are the .oni files.
  const RigCalibration playback = LoadRigCalibration(summary.rig_path);
  ASSERT_EQ(playback.cameras.size(), 2u);
  EXPECT_EQ(playback.cameras[1].uri, summary.files[1].string());
  RigCapture dut(playback, capture);
  const std::int64_t end = MonotonicNs() + 2000000000;
  while ((dut.status(0).frames < 5 || dut.status(1).frames < 5) && MonotonicNs() < end)
    dut.Poll();
  for (int c = 0; c < 2; ++c) {
    ASSERT_GE(dut.status(c).frames, 5u) << c << ": " << dut.status(c).last_error;
    const CameraCalibration& cam = playback.cameras[static_cast<std::size_t>(c)];
    DepthRenderer renderer(cam.intrinsics, cam.X_RigCam);
    renderer.Render(files_.truth.mesh, scene_.floor_z_m);
    DepthNoiseOptions off;
    off.enabled = false;
    std::vector<std::uint16_t> expected(renderer.depth_m().size());
    DepthNoise(off, 1).Apply(renderer.depth_m(), renderer.cos_incidence(), cam.intrinsics.width,
                             cam.intrinsics.height, &expected);
    int differ = 0, max_diff = 0, first = -1;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      const int d = std::abs(int{dut.frame(c).depth_mm[i]} - int{expected[i]});
      if (d != 0 && first < 0) first = static_cast<int>(i);
      differ += d != 0;
      max_diff = std::max(max_diff, d);
    }
    EXPECT_EQ(differ, 0) << "camera " << c << ": max difference " << max_diff << " mm, first at " << first << " played " << (first >= 0 ? dut.frame(c).depth_mm[first] : 0) << " expected " << (first >= 0 ? expected[first] : 0) << " next " << (first >= 0 ? dut.frame(c).depth_mm[first + 1] : 0) << "/" << (first >= 0 ? expected[first + 1] : 0);
  }
}

}  // namespace
}  // namespace vb::perception
