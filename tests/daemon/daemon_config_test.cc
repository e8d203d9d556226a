#include "daemon/daemon_config.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
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
    perception::RingRigOptions real_cameras;  // found by serial: no virtual URIs
    real_cameras.uri_scheme = "";
    perception::SaveRigCalibration(dir_ / "rig.yaml", perception::MakeRingRig(real_cameras));
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

TEST_F(DaemonConfigTest, ProfileOverridesOnlyTheOverridableKeysWithinTheirBounds) {
  const auto path = dir_.Write(
      "vbd.yaml", kHead + "morph: {profile: {dense.rounds: 4, check.unexplained_scale: 0.1}}\n");
  const DaemonConfig c = LoadDaemonConfig(path);
  ASSERT_EQ(c.morph.profile.size(), 2u);
  morph::TemplateArtifact artifact;
  artifact.profile.options.dense.rounds = 7;  // the template's own
  artifact.profile.options.coarse.articulation.rounds = 9;
  const morph::MorphOptions options = MorphOptionsFor(c, artifact);
  EXPECT_EQ(options.dense.rounds, 4);
  EXPECT_EQ(options.check.unexplained_scale, 0.1);
  EXPECT_EQ(options.coarse.articulation.rounds, 9);  // not overridden: the template's

  EXPECT_THAT(Error("morph: {profile: {dense.association.lambda: 5}}\n"),
              HasSubstr("vbd.yaml:5: morph.profile.dense.association.lambda: is the method's own"));
  EXPECT_THAT(Error("morph: {profile: {dense.round: 4}}\n"),
              HasSubstr("vbd.yaml:5: morph.profile.dense.round: unknown key"));
  EXPECT_THAT(Error("morph: {profile: {dense.rounds: 2.5}}\n"),
              HasSubstr("morph.profile.dense.rounds: 2.5 is not a whole number (rounds)"));
  EXPECT_THAT(Error("morph: {profile: {dense.rounds: 0}}\n"),
              HasSubstr("morph.profile.dense.rounds: 0 is outside [1, 50] (rounds)"));
  EXPECT_THAT(Error("morph: {profile: [dense.rounds]}\n"),
              HasSubstr("morph.profile: expected a mapping"));
  // The ambiguity's ramp ends at 1: a start there would leave it no length.
  EXPECT_THAT(Error("morph: {profile: {check.ambiguity_start: 1.0}}\n"),
              HasSubstr("morph.profile.check.ambiguity_start: 1 is outside [0, 0.999]"));
  // Each value in bounds, but together with the template's not: named at start.
  const auto crossed = dir_.Write(
      "crossed.yaml", kHead + "morph: {profile: {check.stretch_start: 0.5, check.stretch_end: 0.4}}\n");
  const DaemonConfig bad = LoadDaemonConfig(crossed);
  try {
    (void)MorphOptionsFor(bad, artifact);
    ADD_FAILURE() << "crossed stretch limits accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("crossed.yaml: morph.profile: with the template's values, "
                                    "check.stretch_start must be below check.stretch_end"));
  }
  // One value given, crossing the template's other one.
  const auto crossed_reach =
      dir_.Write("crossed_reach.yaml", kHead + "morph: {profile: {check.reach_start: 0.07}}\n");
  try {
    (void)MorphOptionsFor(LoadDaemonConfig(crossed_reach), artifact);
    ADD_FAILURE() << "crossed reach limits accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("check.reach_start must be below check.reach_end"));
  }
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

TEST_F(DaemonConfigTest, ListsEveryProblemOfTheFileInOnePass) {
  const std::string all = Error(
      "capture: {fps: 500, frozen_periods: 1}\n"
      "fusion: {voxel_m: fine}\n"
      "job: {min_confidence: 2}\n"
      "lcm: {url: \"udpm://10.0.0.1:7667\"}\n"
      "colour: red\n");
  EXPECT_THAT(all, HasSubstr("vbd.yaml:5: capture.fps: value 500 is outside [1, 120]"));
  EXPECT_THAT(all, HasSubstr("vbd.yaml:5: capture.frozen_periods: value 1 is outside"));
  EXPECT_THAT(all, HasSubstr("vbd.yaml:6: fusion.voxel_m: cannot read 'fine'"));
  EXPECT_THAT(all, HasSubstr("vbd.yaml:7: job.min_confidence: value 2 is outside [0, 1]"));
  EXPECT_THAT(all, HasSubstr("lcm.url: 'udpm://10.0.0.1:7667': 10.0.0.1 is not a multicast"));
  EXPECT_THAT(all, HasSubstr("vbd.yaml:9: colour: unknown key"));
  EXPECT_EQ(std::count(all.begin(), all.end(), '\n'), 5);  // six problems, one per line
}

TEST_F(DaemonConfigTest, RefusesARepeatedKeySoAnAppendedStricterValueCannotBeIgnored) {
  const std::string e =
      Error("job:\n  min_confidence: 0.6\nmemory: {arena_mib: 512}\njob:\n  min_confidence: 0.9\n");
  EXPECT_THAT(e, HasSubstr("vbd.yaml:8: job: repeats the key on line 5"));
  EXPECT_THAT(Error("job: {min_confidence: 0.6, min_confidence: 0.9}\n"),
              HasSubstr("vbd.yaml:5: job.min_confidence: repeats the key on line 5"));
}

TEST_F(DaemonConfigTest, RefusesVirtualCamerasOnARealCanInterfaceUnlessSimulation) {
  perception::SaveRigCalibration(dir_ / "vrig.yaml", perception::MakeRingRig({}));  // vbrig://
  dir_.Write("scene.yaml", "any");
  auto load = [&](const std::string& body) {
    return LoadDaemonConfig(dir_.Write("sim.yaml", "format: virtualbutcherd-config\nversion: 1\n"
                                                   "template: lamb.vbt\n" + body));
  };
  auto error = [&](const std::string& body) {
    try {
      load(body);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  EXPECT_THAT(error("rig: vrig.yaml\ncan: {interface: can0}\n"),
              HasSubstr("sim.yaml:5: can.interface: 'can0' is a real CAN interface, and the "
                        "cameras are virtual (the rig's URIs)"));
  EXPECT_THAT(error("rig: rig.yaml\nvirtual_scene: scene.yaml\ncan: {interface: vcan0}\n"),
              HasSubstr("cameras are virtual (virtual_scene)"));
  // Allowed: real cameras on CAN, virtual cameras on the in-process or socket saw, and
  // virtual cameras on CAN when the file says it is a simulation.
  EXPECT_FALSE(load("rig: rig.yaml\ncan: {interface: can0}\n").simulation);
  EXPECT_FALSE(UsesVirtualCameras(load("rig: rig.yaml\ncan: {interface: can0}\n")));
  EXPECT_NO_THROW(load("rig: vrig.yaml\ncan: {interface: loopback}\n"));
  EXPECT_NO_THROW(load("rig: vrig.yaml\ncan: {interface: \"unix:/tmp/saw.sock\"}\n"));
  EXPECT_TRUE(load("rig: vrig.yaml\nsimulation: true\ncan: {interface: can0}\n").simulation);
  // SIMULATION on every line while real cameras see real carcasses would be a lie.
  EXPECT_THAT(error("rig: rig.yaml\nsimulation: true\ncan: {interface: can0}\n"),
              HasSubstr("sim.yaml:5: simulation: is true, but the cameras are real"));
}

TEST_F(DaemonConfigTest, ARecordingTheRigPlaysIsWalkedBeforeOpenNi2ReadsIt) {
  perception::RingRigOptions playback;
  playback.num_cameras = 2;
  perception::RigCalibration rig = perception::MakeRingRig(playback);
  rig.cameras[0].uri = (dir_ / "cam0.oni").string();
  rig.cameras[1].uri = (dir_ / "cam1.oni").string();
  dir_.Write("cam0.oni", "a text file someone renamed");
  perception::SaveRigCalibration(dir_ / "playback.yaml", rig);
  const std::string both = [&] {
    try {
      LoadDaemonConfig(dir_.Write("play.yaml", "format: virtualbutcherd-config\nversion: 1\n"
                                               "template: lamb.vbt\nrig: playback.yaml\n"));
    } catch (const InputError& error) {
      return std::string(error.what());
    }
    return std::string("(accepted)");
  }();
  EXPECT_THAT(both, HasSubstr((dir_ / "cam0.oni").string() + ": at byte 0: not an OpenNI recording"));
  EXPECT_THAT(both, HasSubstr((dir_ / "cam1.oni").string() + ": not a recording file"));
}

TEST_F(DaemonConfigTest, AKeyThatIsNotAPlainValueIsAProblemNotACrash) {
  EXPECT_THAT(Error("capture: {? [fps, x] : 3, fps: 500}\n"),
              HasSubstr("vbd.yaml:5: capture.?: expected a single value"));
  EXPECT_THAT(Error("capture: {? [fps, x] : 3, fps: 500}\n"),
              HasSubstr("capture.fps: value 500 is outside"));
  EXPECT_THAT(Error("? {a: 1}\n: 2\n"), HasSubstr("vbd.yaml:5: ?: expected a single value"));
}

TEST(DaemonConfigLcmUrlTest, AcceptsWhatLcmPublishesOnAndNamesWhatIsWrong) {
  EXPECT_EQ(CheckLcmUrl("memq://"), "");
  EXPECT_EQ(CheckLcmUrl("udpm://239.255.76.67:7667?ttl=0"), "");
  EXPECT_EQ(CheckLcmUrl("udpm://224.0.0.1:1?ttl=255&recv_buf_size=2097152"), "");
  EXPECT_THAT(CheckLcmUrl("udpm://239.255.76.67"), HasSubstr("expected udpm://ADDRESS:PORT"));
  EXPECT_THAT(CheckLcmUrl("udpm://239.255.76:7667"), HasSubstr("is not an IPv4 address"));
  EXPECT_THAT(CheckLcmUrl("udpm://192.168.1.2:7667"), HasSubstr("is not a multicast address"));
  EXPECT_THAT(CheckLcmUrl("udpm://239.1.1.1:70000"), HasSubstr("port '70000' is not in"));
  EXPECT_THAT(CheckLcmUrl("udpm://239.1.1.1:x?ttl=0"), HasSubstr("port 'x' is not in"));
  EXPECT_THAT(CheckLcmUrl("udpm://239.1.1.1:7667?ttl=256"), HasSubstr("ttl '256' is not in"));
  EXPECT_THAT(CheckLcmUrl("udpm://239.1.1.1:7667?tll=1"), HasSubstr("unknown option 'tll'"));
  EXPECT_THAT(CheckLcmUrl("tcpq://x"), HasSubstr("is neither udpm:// nor memq://"));
}

TEST_F(DaemonConfigTest, ChecksWhatThisMachineMustOfferBeforeStart) {
  auto problems = [&](const std::string& body, std::vector<std::string>* warnings = nullptr) {
    const DaemonConfig c = LoadDaemonConfig(dir_.Write("vbd.yaml", kHead + body));
    std::string all;
    for (const std::string& p : CheckMachine(c, warnings)) all += p + "\n";
    return all;
  };
  EXPECT_EQ(problems("can: {interface: loopback}\n"), "");
  EXPECT_THAT(problems("can: {interface: nosuch0}\n"),
              HasSubstr("vbd.yaml: can.interface: 'nosuch0': no such network interface"));
  // Every Linux machine has lo; it is not a CAN interface (ARPHRD_LOOPBACK, 772).
  EXPECT_THAT(problems("can: {interface: lo}\n"),
              HasSubstr("can.interface: 'lo' is not a CAN interface (link type 772"));
  EXPECT_THAT(problems("can: {interface: \"unix:/nowhere/saw.sock\"}\n"),
              HasSubstr("can.interface: no folder /nowhere"));
  EXPECT_THAT(problems("can: {interface: loopback, record: nowhere/frames.log}\n"),
              HasSubstr("can.record: no folder"));
  EXPECT_THAT(problems("can: {interface: loopback}\njob: {dump_dir: nowhere}\n"),
              HasSubstr("job.dump_dir: no folder"));
  EXPECT_EQ(problems("can: {interface: loopback, record: \"\"}\njob: {dump_dir: \"\"}\n"), "");
  std::vector<std::string> warnings;
  EXPECT_EQ(problems("can: {interface: loopback}\njob: {state_file: nowhere/job-state}\n",
                     &warnings),
            "");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], HasSubstr("job.state_file: no folder"));
}

TEST(DaemonConfigShippedTest, TheShippedFileListsEveryKeyAndLoadsBesideItsRig) {
  // config/virtualbutcherd.yaml as shipped, beside the shipped rig.yaml, with a template of
  // that name: it loads (the HIL test runs --check-config on it unchanged, with can0).
  test::TempDir dir;
  std::filesystem::copy_file(VB_SOURCE_DIR "/config/virtualbutcherd.yaml", dir / "vbd.yaml");
  std::filesystem::copy_file(VB_SOURCE_DIR "/config/rig.yaml", dir / "rig.yaml");
  dir.Write("lamb.vbt", "x");
  const DaemonConfig c = LoadDaemonConfig(dir / "vbd.yaml");
  EXPECT_EQ(c.template_path, dir / "lamb.vbt");
  EXPECT_EQ(c.can.interface, "can0");
  EXPECT_EQ(c.can.answer_timeout_ms, 250);
  EXPECT_TRUE(c.can.record.empty());
  EXPECT_TRUE(c.job.dump_dir.empty());
  EXPECT_FALSE(c.simulation);
  EXPECT_FALSE(UsesVirtualCameras(c));
  EXPECT_TRUE(c.morph.upright.enabled);
  // Every key the loader knows is written out (virtual_scene as a comment: it is a choice,
  // not a default).
  const YAML::Node root = YAML::LoadFile((dir / "vbd.yaml").string());
  for (const std::string& key : DaemonConfigKeys()) {
    if (key == "virtual_scene") continue;
    const std::size_t dot = key.find('.');
    const bool present = dot == std::string::npos
                             ? static_cast<bool>(root[key])
                             : static_cast<bool>(root[key.substr(0, dot)][key.substr(dot + 1)]);
    EXPECT_TRUE(present) << key << " is not in config/virtualbutcherd.yaml";
  }
}

}  // namespace
}  // namespace vb::daemon
