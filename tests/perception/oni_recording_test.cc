#include "perception/oni_recording.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <string>

#include "io/oni_file.h"

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

  // The walk that runs before OpenNI2's player accepts what OpenNI2's recorder wrote.
  const io::OniSummary oni = io::CheckOniFile(summary.files[0]);
  ASSERT_EQ(oni.nodes.size(), 1u);
  EXPECT_EQ(oni.nodes[0].type, 2u);  // depth
  EXPECT_EQ(oni.nodes[0].width, playback.cameras[0].intrinsics.width);
  EXPECT_EQ(oni.nodes[0].height, playback.cameras[0].intrinsics.height);
  EXPECT_EQ(oni.nodes[0].data_records, oni.nodes[0].frames);
  EXPECT_GE(oni.nodes[0].data_records, 10u);
}

TEST_F(OniRecordingTest, AnUnsoundRecordingIsRefusedBeforeOpenNi2ReadsIt) {
  perception::VirtualRigOptions options;
  options.ring.num_cameras = 1;
  WriteRig(options);
  RecordOptions record;
  record.out_dir = dir_ / "recording";
  record.seconds = 0.5;
  const RecordSummary summary = RecordOni(scene_.rig, CaptureOptions{}, record);
  ASSERT_EQ(summary.files.size(), 1u);
  // The first frame's payload size word (the record after the node's properties) claims
  // 2 GB: OpenNI2 would read it as a frame.
  std::string bytes;
  {
    std::ifstream in(summary.files[0], std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::size_t at = 24;
  for (;;) {
    std::uint32_t head[5];
    ASSERT_LE(at + 28, bytes.size());
    std::memcpy(head, bytes.data() + at, sizeof head);
    if (head[1] == 0x0A) break;  // the first frame
    at += head[3] + head[4];
  }
  const std::uint32_t claim = 0x7fffffff;
  std::memcpy(&bytes[at + 16], &claim, 4);
  std::ofstream(summary.files[0], std::ios::binary | std::ios::trunc) << bytes;

  const RigCalibration playback = LoadRigCalibration(summary.rig_path);
  RigCapture dut(playback, CaptureOptions{});
  dut.Poll();
  EXPECT_EQ(dut.status(0).health, CameraHealth::kMissing);
  EXPECT_THAT(dut.status(0).last_error,
              ::testing::HasSubstr("at byte " + std::to_string(at) +
                                   ": a record payload of 2147483647 bytes, more than the limit"));
  EXPECT_EQ(dut.status(0).frames, 0u);
}

}  // namespace
}  // namespace vb::perception
