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
  // Each camera's recording, replayed for 3 s (it loops), against a fresh noise-free render:
  // every played frame must be exact.
  std::vector<std::vector<std::uint16_t>> expected;
  for (const CameraCalibration& cam : playback.cameras) {
    DepthRenderer renderer(cam.intrinsics, cam.X_RigCam);
    renderer.Render(files_.truth.mesh, scene_.floor_z_m);
    DepthNoiseOptions off;
    off.enabled = false;
    expected.emplace_back(renderer.depth_m().size());
    DepthNoise(off, 1).Apply(renderer.depth_m(), renderer.cos_incidence(), cam.intrinsics.width,
                             cam.intrinsics.height, &expected.back());
  }
  int exact[2] = {0, 0}, played[2] = {0, 0};
  std::uint64_t seen[2] = {0, 0};
  const std::int64_t end = MonotonicNs() + 3000000000;
  while (MonotonicNs() < end) {
    dut.Poll();
    for (int c = 0; c < 2; ++c) {
      if (dut.status(c).frames == seen[c]) continue;
      seen[c] = dut.status(c).frames;
      ++played[c];
      exact[c] += dut.frame(c).depth_mm == expected[static_cast<std::size_t>(c)];
    }
  }
  for (int c = 0; c < 2; ++c) {
    std::printf("camera %d: %d of %d played frames equal the render\n", c, exact[c], played[c]);
    EXPECT_GE(played[c], 30) << c;
    EXPECT_EQ(exact[c], played[c]) << c;
  }
}

}  // namespace
}  // namespace vb::perception
