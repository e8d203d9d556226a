#include "daemon/daemon_config.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::daemon {
namespace {

using ::testing::HasSubstr;

class DaemonConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    perception::SaveRigCalibration(dir_ / "rig.yaml", perception::MakeRingRig({}));
    dir_.Write("lamb.vbt", "a compiled template");
  }
  std::string Error(const std::string& body) {
    const auto path = dir_.Write("vbd.yaml", kHead + body);
    try {
      LoadDaemonConfig(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "(accepted)";
  }
  const std::string kHead =
      "format: virtualbutcherd-config\nversion: 1\ntemplate: lamb.vbt\nrig: rig.yaml\n";
  test::TempDir dir_;
};

TEST_F(DaemonConfigTest, ReadsEverySectionWithDefaultsForTheRest) {
  const auto path = dir_.Write(
      "vbd.yaml", kHead +
                      "capture: {fps: 15, recovery_period_ms: 2000}\n"
                      "fusion: {voxel_m: 0.008, max_points: 40000, roi_min: [-1, -1, -2], "
                      "roi_max: [1, 1, 0.2]}\n"
                      "job: {presence_min_points: 3000, min_confidence: 0.7}\n"
                      "lcm: {url: \"memq://\", status_channel: LINE3_STATUS}\n"
                      "can: {interface: vcan0}\n"
                      "memory: {arena_mib: 1024}\n"
                      "X_SawRig: {translation: [0, 0, 1.8], rotation_wxyz: [1, 0, 0, 0]}\n");
  const DaemonConfig c = LoadDaemonConfig(path);
  EXPECT_EQ(c.capture.fps, 15);
  EXPECT_EQ(c.capture.recovery_period_ms, 2000);
  EXPECT_EQ(c.capture.frozen_periods, 5);  // default
  EXPECT_EQ(c.fusion.voxel_m, 0.008);
  EXPECT_EQ(c.fusion.roi.min().z(), -2);
  EXPECT_EQ(c.job.min_confidence, 0.7);
  EXPECT_EQ(c.lcm.channels.status, "LINE3_STATUS");
  EXPECT_EQ(c.lcm.channels.cut_lines, "VB_CUT_LINES");
  EXPECT_EQ(c.can.interface, "vcan0");
  EXPECT_EQ(c.memory.arena_mib, 1024);
  EXPECT_EQ(c.X_SawRig.translation().z(), 1.8);
  EXPECT_EQ(c.rig.cameras.size(), 4u);
  EXPECT_EQ(c.template_path, dir_ / "lamb.vbt");
  EXPECT_FALSE(c.morph.upright.enabled);  // any orientation unless the line says
}

TEST_F(DaemonConfigTest, ReadsTheUprightPriorAndRefusesHalfOfIt) {
  const auto path =
      dir_.Write("vbd.yaml",
                 kHead + "morph: {template_up: [0, 0, 2], rig_up: [0, -1, 0], max_tilt_deg: 30}\n");
  const DaemonConfig c = LoadDaemonConfig(path);
  ASSERT_TRUE(c.morph.upright.enabled);
  EXPECT_EQ(c.morph.upright.template_up, Eigen::Vector3d(0, 0, 1));  // normalised
  EXPECT_EQ(c.morph.upright.target_up, Eigen::Vector3d(0, -1, 0));
  EXPECT_EQ(c.morph.upright.max_tilt_deg, 30);
  EXPECT_THAT(Error("morph: {template_up: [0, 0, 1]}\n"),
              HasSubstr("morph.rig_up: is needed with the other upright keys"));
  EXPECT_THAT(Error("morph: {template_up: [0, 0, 0], rig_up: [0, 0, 1]}\n"),
              HasSubstr("morph.template_up: must not be zero"));
  EXPECT_THAT(Error("morph: {template_up: [0, 0, 1], rig_up: [0, 0, 1], max_tilt_deg: 0}\n"),
              HasSubstr("morph.max_tilt_deg: value 0 is outside [1, 180]"));
  EXPECT_THAT(Error("morph: {upright: yes}\n"), HasSubstr("morph.upright: unknown key"));
}

TEST_F(DaemonConfigTest, ReadsTheSawLinkAndJobNumberingKeys) {
  const auto path = dir_.Write(
      "vbd.yaml", kHead +
                      "can: {interface: \"unix:/run/vbsaw.sock\", answer_timeout_ms: 400, "
                      "record: frames.log}\n"
                      "job: {state_file: job-state, morph_deadline_ms: 1500, "
                      "new_carcass_change: 0.5}\n");
  const DaemonConfig c = LoadDaemonConfig(path);
  EXPECT_EQ(c.can.interface, "unix:/run/vbsaw.sock");
  EXPECT_EQ(c.can.answer_timeout_ms, 400);
  EXPECT_EQ(c.can.record, dir_ / "frames.log");
  EXPECT_EQ(c.job.state_file, dir_ / "job-state");
  EXPECT_EQ(c.job.morph_deadline_ms, 1500);
  EXPECT_EQ(c.job.new_carcass_change, 0.5);
  EXPECT_THAT(Error("can: {answer_timeout_ms: 0}\n"),
              HasSubstr("can.answer_timeout_ms: value 0 is outside [10, 5000]"));
  EXPECT_THAT(Error("job: {state_file: nowhere/job-state}\n"),
              HasSubstr("job.state_file: no folder"));
  EXPECT_THAT(Error("can: {record: nowhere/frames.log}\n"), HasSubstr("can.record: no folder"));
  EXPECT_THAT(Error("job: {morph_deadline_ms: 10}\n"),
              HasSubstr("job.morph_deadline_ms: value 10 is outside [50, 600000]"));
  EXPECT_THAT(Error("can: {interface: \"unix:/" + std::string(120, 'x') + "\"}\n"),
              HasSubstr("the socket path is longer than 107 characters"));
}

TEST_F(DaemonConfigTest, NamesFileLineKeyAndValue) {
  EXPECT_THAT(Error("capture: {fsp: 30}\n"), HasSubstr("vbd.yaml:5: capture.fsp: unknown key"));
  EXPECT_THAT(Error("captur: {fps: 30}\n"), HasSubstr("captur: unknown key"));
  EXPECT_THAT(Error("capture: {fps: 500}\n"),
              HasSubstr("capture.fps: value 500 is outside [1, 120]"));
  EXPECT_THAT(Error("fusion: {voxel_m: fine}\n"), HasSubstr("fusion.voxel_m: cannot read 'fine'"));
  EXPECT_THAT(Error("fusion: {roi_min: [1, 1, 1], roi_max: [0, 0, 0]}\n"),
              HasSubstr("region of interest is empty"));
  EXPECT_THAT(Error("lcm: {url: \"tcpq://x\"}\n"), HasSubstr("lcm.url: 'tcpq://x' is neither"));
  EXPECT_THAT(Error("can: {interface: a-very-long-interface-name}\n"),
              HasSubstr("can.interface: 'a-very-long-interface-name' is longer"));
  EXPECT_THAT(Error("job: {presence_min_points: 100000}\n"),
              HasSubstr("job.presence_min_points: is larger than fusion.max_points"));
  EXPECT_THAT(Error("X_SawRig: {translation: [0, 0, 0], rotation_wxyz: [2, 0, 0, 0]}\n"),
              HasSubstr("X_SawRig.rotation_wxyz: is not a unit quaternion"));
  EXPECT_THAT(Error("virtual_scene: nowhere.yaml\n"), HasSubstr("virtual_scene: no file"));
  EXPECT_THAT(Error("memory: {arena_mib: 64}\n"),
              HasSubstr("memory.arena_mib: value 64 is outside [128, 16384]"));
  EXPECT_THAT(Error("memory: {arena: 512}\n"), HasSubstr("memory.arena: unknown key"));
  const auto missing =
      dir_.Write("m.yaml", "format: virtualbutcherd-config\nversion: 1\nrig: rig.yaml\n");
  EXPECT_THROW(LoadDaemonConfig(missing), InputError);
  const auto no_template = dir_.Write("t.yaml",
                                      "format: virtualbutcherd-config\nversion: 1\n"
                                      "template: absent.vbt\nrig: rig.yaml\n");
  try {
    LoadDaemonConfig(no_template);
    ADD_FAILURE();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("t.yaml:3: template: no file"));
  }
}

TEST(DaemonConfigShippedTest, TheShippedExampleIsValidOnceItsFilesExist) {
  // config/virtualbutcherd.yaml names installed paths; here only its syntax and keys are
  // checked, against a copy whose paths point at files that exist.
  test::TempDir dir;
  perception::SaveRigCalibration(dir / "rig.yaml", perception::MakeRingRig({}));
  dir.Write("lamb.vbt", "x");
  std::ifstream in(VB_SOURCE_DIR "/config/virtualbutcherd.yaml");
  ASSERT_TRUE(in.good());
  std::stringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  s.replace(s.find("/usr/share/virtualbutcher/lamb.vbt"), 34, "lamb.vbt");
  s.replace(s.find("/etc/virtualbutcher/rig.yaml"), 28, "rig.yaml");
  s.replace(s.find("/var/lib/virtualbutcher/job-state"), 33, "job-state");
  const DaemonConfig c = LoadDaemonConfig(dir.Write("vbd.yaml", s));
  EXPECT_EQ(c.can.interface, "can0");
  EXPECT_EQ(c.can.answer_timeout_ms, 250);
  EXPECT_EQ(c.job.state_file, dir / "job-state");
  EXPECT_TRUE(c.morph.upright.enabled);
}

}  // namespace
}  // namespace vb::daemon
