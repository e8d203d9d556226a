#include "perception/oni_recording.h"

#include <OpenNI.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "io/oni_file.h"
#include "perception/depth_noise.h"
#include "perception/depth_renderer.h"
#include "tests/support/temp_dir.h"
#include "tests/support/virtual_rig_fixture.h"

namespace vb::perception {
namespace {

// Records the virtual camera @p serial for @p seconds with its depth stream in @p format,
// mirrored or not, through OpenNI2's own recorder, as a camera another program (a viewer)
// left in that mode would be. Returns an empty string, or what failed.
// @pre OpenNI2 is not in use in this process.
std::string RecordInFormat(const std::string& serial, openni::PixelFormat format, bool mirrored,
                           const std::filesystem::path& file, double seconds) {
  // Through capture's own start first, which keeps OpenNI2's drivers loaded for the life of
  // the process: unloaded by the shutdown below, their blocks would read as leaks of an
  // unknown module that no suppression names.
  (void)ListDevices();
  if (openni::OpenNI::initialize() != openni::STATUS_OK) return "initialise";
  std::string failed;
  {
    openni::Device device;
    openni::VideoStream depth;
    openni::Recorder recorder;
    if (device.open(("vbrig://" + serial).c_str()) != openni::STATUS_OK) {
      failed = "open";
    } else if (depth.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      failed = "create";
    } else {
      openni::VideoMode mode = depth.getVideoMode();
      mode.setPixelFormat(format);
      if (depth.setVideoMode(mode) != openni::STATUS_OK ||
          depth.setMirroringEnabled(mirrored) != openni::STATUS_OK ||
          depth.start() != openni::STATUS_OK ||
          recorder.create(file.c_str()) != openni::STATUS_OK ||
          recorder.attach(depth) != openni::STATUS_OK || recorder.start() != openni::STATUS_OK)
        failed = std::string("record: ") + openni::OpenNI::getExtendedError();
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
      recorder.stop();
      recorder.destroy();
      depth.stop();
      depth.destroy();
      device.close();
    }
  }
  openni::OpenNI::shutdown();
  return failed;
}

class OniRecordingTest : public test::VirtualRigTest {
 protected:
  // Records camera 0 of a one-camera noise-free rig in @p format, @p mirrored or not, and plays
  // the recording through capture: every frame must be the render in millimetres as the lens
  // sees it.
  void ExpectPlaysAsTheLensSees(openni::PixelFormat format, bool mirrored) {
    perception::VirtualRigOptions options;
    options.ring.num_cameras = 1;
    options.noise = false;
    WriteRig(options);
    const std::filesystem::path file = dir_ / "recorded.oni";
    const RigCalibration& rig_calibration = scene_.rig;
    ASSERT_EQ(RecordInFormat(rig_calibration.cameras[0].serial, format, mirrored, file, 1.0), "");
    const DeviceListing listed = DescribeUri(file.string());
    EXPECT_EQ(listed.error, "");
    EXPECT_THAT(listed.depth_mode, ::testing::HasSubstr(
                                       format == openni::PIXEL_FORMAT_DEPTH_100_UM ? "depth 100 um"
                                                                                   : "depth 1 mm"));
    EXPECT_TRUE(listed.depth_readable);
    EXPECT_EQ(listed.mirrored, mirrored);
    EXPECT_GE(listed.recorded_frames, 10);
    EXPECT_NEAR(listed.fx_from_fov, rig_calibration.cameras[0].intrinsics.fx, 0.01);

    // Capture asks for millimetres, not mirrored; the player keeps what was recorded.
    RigCalibration playback = rig_calibration;
    playback.cameras[0].uri = file.string();
    const CameraCalibration& cam = playback.cameras[0];
    const std::vector<std::uint16_t> expected = NoiseFreeRender(cam);
    if (mirrored) {  // the recording is not the same read either way round
      std::vector<std::uint16_t> reversed(expected.size());
      for (int v = 0; v < cam.intrinsics.height; ++v)
        std::reverse_copy(expected.begin() + v * cam.intrinsics.width,
                          expected.begin() + (v + 1) * cam.intrinsics.width,
                          reversed.begin() + v * cam.intrinsics.width);
      ASSERT_NE(reversed, expected);
    }
    const auto [played, exact] = PlayedAndExact(playback, expected, 1.5);
    EXPECT_GE(played, 10);
    EXPECT_EQ(exact, played);
  }

  // Camera 0's noise-free render in millimetres, as the virtual driver gives it.
  std::vector<std::uint16_t> NoiseFreeRender(const CameraCalibration& cam) const {
    DepthRenderer renderer(cam.intrinsics, cam.X_RigCam);
    renderer.Render(files_.truth.mesh, scene_.floor_z_m);
    DepthNoiseOptions off;
    off.enabled = false;
    std::vector<std::uint16_t> depth(renderer.depth_m().size());
    DepthNoise(off, 1).Apply(renderer.depth_m(), renderer.cos_incidence(), cam.intrinsics.width,
                             cam.intrinsics.height, &depth);
    return depth;
  }

  // Camera 0 of @p rig captured for @p seconds: the frames played, and how many equal
  // @p expected.
  static std::pair<int, int> PlayedAndExact(const RigCalibration& rig,
                                            const std::vector<std::uint16_t>& expected,
                                            double seconds) {
    CaptureOptions capture;
    capture.recovery_period_ms = 60000;  // a static noise-free scene repeats itself exactly
    RigCapture dut(rig, capture);
    int exact = 0, played = 0;
    std::uint64_t seen = 0;
    const std::int64_t end = MonotonicNs() + static_cast<std::int64_t>(seconds * 1e9);
    while (MonotonicNs() < end) {
      dut.Poll();
      if (dut.status(0).frames == seen) continue;
      seen = dut.status(0).frames;
      ++played;
      exact += dut.frame(0).depth_mm == expected;
    }
    return {played, exact};
  }
};

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

// A camera that never streams is left out of the playback rig, named with the reason, and leaves
// no file that could pass for its recording (here, one left by an earlier recording into the same
// folder); the others are recorded whole.
TEST_F(OniRecordingTest, ACameraThatDoesNotStreamIsLeftOutAndNamed) {
  perception::VirtualRigOptions options;
  options.ring.num_cameras = 2;
  WriteRig(options);
  SetFault(scene_.rig.cameras[1].serial, CameraFault::kMissing);
  RecordOptions record;
  record.out_dir = dir_ / "recording";
  record.seconds = 0.5;
  const std::filesystem::path stale = record.out_dir / (scene_.rig.cameras[1].serial + ".oni");
  std::filesystem::create_directories(record.out_dir);
  std::ofstream(stale) << "an earlier take";
  const RecordSummary summary = RecordOni(scene_.rig, CaptureOptions{}, record);
  ASSERT_EQ(summary.files.size(), 1u);
  ASSERT_EQ(summary.left_out.size(), 1u);
  EXPECT_THAT(summary.left_out[0],
              ::testing::HasSubstr(scene_.rig.cameras[1].name + ": not streaming"));
  EXPECT_FALSE(std::filesystem::exists(stale));
  EXPECT_GE(io::CheckOniFile(summary.files[0]).nodes.at(0).frames, 7u);  // 15 at 30 fps
  EXPECT_FALSE(std::filesystem::exists(summary.files[0].string() + ".part"));
  EXPECT_EQ(LoadRigCalibration(summary.rig_path).cameras.size(), 1u);
}

// A camera whose recorder has not answered grace_seconds after the take should have ended
// (here its stream's first frame comes 10 s late, and the child waits for it) is killed and left
// out, and nothing of it is left in the folder; with no camera recorded, no playback rig.
TEST_F(OniRecordingTest, ARecorderThatDoesNotFinishInTimeIsKilledAndNamed) {
  perception::VirtualRigOptions options;
  options.ring.num_cameras = 1;
  WriteRig(options);
  SetStartDelay(10000);
  CaptureOptions capture;
  capture.first_frame_timeout_ms = 20000;
  RecordOptions record;
  record.out_dir = dir_ / "recording";
  record.seconds = 0.2;
  record.grace_seconds = 1.5;
  const std::filesystem::path file = record.out_dir / (scene_.rig.cameras[0].serial + ".oni");
  std::filesystem::create_directories(record.out_dir);
  std::ofstream(file) << "an earlier take";
  std::ofstream(file.string() + ".part") << "an earlier take's partial file";
  std::ofstream(record.out_dir / "rig.yaml") << "an earlier take's rig";
  std::string error;
  const auto start = std::chrono::steady_clock::now();
  try {
    RecordOni(scene_.rig, capture, record);
  } catch (const std::runtime_error& e) {
    error = e.what();
  }
  // Killed, not waited for: the child would answer after the first frame, 10 s in.
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(6));
  EXPECT_THAT(error, ::testing::HasSubstr(scene_.rig.cameras[0].name +
                                          ": its recorder had not finished 1.7 s after"));
  EXPECT_FALSE(std::filesystem::exists(file));
  EXPECT_FALSE(std::filesystem::exists(file.string() + ".part"));
  EXPECT_FALSE(std::filesystem::exists(record.out_dir / "rig.yaml"));
}

TEST(RecordOptionsTest, ALengthOrGraceOutOfRangeIsRefusedBeforeAnyCameraIsTouched) {
  const test::TempDir dir;
  const RigCalibration rig;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const auto& [seconds, grace] : std::vector<std::pair<double, double>>{
           {0, 60}, {-1, 60}, {nan, 60}, {3601, 60}, {1, 0.5}, {1, 3601}, {1, inf}, {1, nan}}) {
    RecordOptions record;
    record.out_dir = dir / "never";
    record.seconds = seconds;
    record.grace_seconds = grace;
    EXPECT_THROW(RecordOni(rig, CaptureOptions{}, record), std::invalid_argument)
        << "seconds " << seconds << ", grace " << grace;
    EXPECT_FALSE(std::filesystem::exists(record.out_dir));
  }
}

TEST_F(OniRecordingTest, ARecordingInTenthsOfAMillimetrePlaysInMillimetres) {
  ExpectPlaysAsTheLensSees(openni::PIXEL_FORMAT_DEPTH_100_UM, false);
}

TEST_F(OniRecordingTest, AMirroredRecordingPlaysAsTheLensSees) {
  ExpectPlaysAsTheLensSees(openni::PIXEL_FORMAT_DEPTH_1_MM, true);
}

// A live camera whose driver mirrors by default: capture switches it back (or, should it
// refuse, turns its rows back), so frames are as the lens sees them either way.
TEST_F(OniRecordingTest, ACameraThatMirrorsIsSwitchedBack) {
  perception::VirtualRigOptions options;
  options.ring.num_cameras = 1;
  options.noise = false;
  WriteRig(options);
  const std::vector<std::uint16_t> expected = NoiseFreeRender(scene_.rig.cameras[0]);
  setenv("VB_VIRTUAL_MIRROR", "1", 1);  // the driver's streams start mirrored
  const auto [played, exact] = PlayedAndExact(scene_.rig, expected, 1.0);
  unsetenv("VB_VIRTUAL_MIRROR");
  EXPECT_GE(played, 10);
  EXPECT_EQ(exact, played);
}

TEST(DepthUnitsTest, TenthsAreRoundedToMillimetresAndShiftsAreRefused) {
  // Two rows of three, a stride of four: the fourth of each row is padding.
  const std::vector<std::uint16_t> tenths = {0, 14, 15, 9, 12345, 65535, 10, 7};
  std::vector<std::uint16_t> mm(6, 1);
  ASSERT_TRUE(CopyDepthAsMillimetres(openni::PIXEL_FORMAT_DEPTH_100_UM, tenths.data(), 4, 3, 2,
                                     false, mm.data()));
  EXPECT_EQ(mm, (std::vector<std::uint16_t>{0, 1, 2, 1235, 6554, 1}));
  ASSERT_TRUE(CopyDepthAsMillimetres(openni::PIXEL_FORMAT_DEPTH_100_UM, tenths.data(), 4, 3, 2,
                                     true, mm.data()));
  EXPECT_EQ(mm, (std::vector<std::uint16_t>{2, 1, 0, 1, 6554, 1235}));
  ASSERT_TRUE(CopyDepthAsMillimetres(openni::PIXEL_FORMAT_DEPTH_1_MM, tenths.data(), 4, 3, 2,
                                     true, mm.data()));
  EXPECT_EQ(mm, (std::vector<std::uint16_t>{15, 14, 0, 10, 65535, 12345}));
  ASSERT_TRUE(CopyDepthAsMillimetres(openni::PIXEL_FORMAT_DEPTH_1_MM, tenths.data(), 4, 3, 2,
                                     false, mm.data()));
  EXPECT_EQ(mm, (std::vector<std::uint16_t>{0, 14, 15, 12345, 65535, 10}));
  const std::vector<std::uint16_t> before = mm;
  EXPECT_FALSE(CopyDepthAsMillimetres(openni::PIXEL_FORMAT_SHIFT_9_2, tenths.data(), 4, 3, 2,
                                      false, mm.data()));
  EXPECT_EQ(mm, before);
  EXPECT_EQ(DescribePixelFormat(openni::PIXEL_FORMAT_SHIFT_9_3), "shift 9.3");
  EXPECT_EQ(DescribePixelFormat(12345), "format 12345");
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
