// Rig calibration from depth alone: the sphere target hung in the virtual rig, rendered by our
// OpenNI2 driver at the sensor noise model, captured through OpenNI2, its spheres found, and
// every camera pose solved from perturbed starting poses; then the cross-camera check on it.
#include "perception/rig_calibrator.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "io/error.h"
#include "io/mesh_io.h"
#include "perception/depth_noise.h"
#include "perception/depth_renderer.h"
#include "perception/virtual_scene.h"
#include "tests/support/temp_dir.h"

namespace vb::perception {
namespace {

using ::testing::HasSubstr;

Eigen::Isometry3d Yaw(double deg) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return X;
}

// @p X moved by @p mm along a random direction and turned by @p deg about a random axis
// through its own centre.
Eigen::Isometry3d Perturb(const Eigen::Isometry3d& X, double mm, double deg, std::mt19937* rng) {
  std::normal_distribution<double> n;
  const Eigen::Vector3d dir = Eigen::Vector3d(n(*rng), n(*rng), n(*rng)).normalized();
  const Eigen::Vector3d axis = Eigen::Vector3d(n(*rng), n(*rng), n(*rng)).normalized();
  Eigen::Isometry3d out = X;
  out.translation() += 1e-3 * mm * dir;
  out.linear() = Eigen::AngleAxisd(deg * M_PI / 180, axis).toRotationMatrix() * X.linear();
  return out;
}

// What @p cam sees of @p mesh_Rig (and the floor): one frame at the sensor model.
std::vector<std::uint16_t> NoisyDepth(const CameraCalibration& cam, const geometry::TriangleMesh& mesh_Rig,
                                      std::uint64_t seed) {
  DepthRenderer renderer(cam.intrinsics, cam.X_RigCam);
  renderer.Render(mesh_Rig, -2.2);
  std::vector<std::uint16_t> depth(renderer.depth_m().size());
  DepthNoise(DepthNoiseOptions{}, seed).Apply(renderer.depth_m(), renderer.cos_incidence(),
                                              cam.intrinsics.width, cam.intrinsics.height, &depth);
  return depth;
}

// The pixels of @p depth with a reading.
int Readings(const std::vector<std::uint16_t>& depth) {
  return static_cast<int>(std::count_if(depth.begin(), depth.end(), [](auto z) { return z != 0; }));
}

// The same, as points.
Eigen::Matrix3Xd NoisyView(const CameraCalibration& cam, const geometry::TriangleMesh& mesh_Rig,
                           std::uint64_t seed) {
  return DepthToPoints(NoisyDepth(cam, mesh_Rig, seed), cam.intrinsics);
}

// Two frames of a still target differ in a handful of pixels (the sensor's noise); the
// target moved by 2 cm across the view, 4 cm along it or turned on its hook differs in
// hundreds, whichever frame is first.
TEST(MovedPixelsTest, NoiseIsStillAndAMovedTargetIsNot) {
  const CalibrationTarget target = DefaultCalibrationTarget();
  const RigCalibration rig = MakeRingRig({});
  for (const CameraCalibration& cam : rig.cameras) {
    const int w = cam.intrinsics.width, h = cam.intrinsics.height;
    const auto a = NoisyDepth(cam, TargetMesh(target), 1);
    const auto b = NoisyDepth(cam, TargetMesh(target), 2);
    // 2 cm across the camera's view (level), then 4 cm along it.
    const Eigen::Vector3d along = cam.X_RigCam.linear().col(2);
    const Eigen::Vector3d across = along.cross(Eigen::Vector3d::UnitZ()).normalized();
    Eigen::Isometry3d shifted = Eigen::Isometry3d::Identity(), nearer = shifted;
    shifted.translation() = 0.02 * across;
    nearer.translation() = -0.04 * along;
    const auto moved = NoisyDepth(cam, TargetMesh(target, shifted), 2);
    const auto closer = NoisyDepth(cam, TargetMesh(target, nearer), 2);
    const auto turned = NoisyDepth(cam, TargetMesh(target, Yaw(120)), 2);
    const int valid = Readings(b);
    const int still = MovedPixels(a, b, w, h);
    const int by_shift = MovedPixels(a, moved, w, h), back = MovedPixels(moved, a, w, h);
    const int by_turn = MovedPixels(a, turned, w, h), by_approach = MovedPixels(a, closer, w, h);
    std::printf("%s: %d readings; still %d, 2 cm across %d (%d the other way), 4 cm nearer %d, "
                "turned %d\n",
                cam.name.c_str(), valid, still, by_shift, back, by_approach, by_turn);
    EXPECT_FALSE(SceneMoved(still, valid)) << cam.name;
    EXPECT_TRUE(SceneMoved(by_shift, valid)) << cam.name;
    EXPECT_TRUE(SceneMoved(back, valid)) << cam.name;
    EXPECT_TRUE(SceneMoved(by_approach, valid)) << cam.name;
    EXPECT_TRUE(SceneMoved(by_turn, valid)) << cam.name;
  }
}

TEST(CalibrationTargetTest, TheDefaultTargetCanCalibrateAndBadOnesAreNamed) {
  const CalibrationTarget target = DefaultCalibrationTarget();
  EXPECT_TRUE(CheckCalibrationTarget(target).empty());
  CalibrationTarget same_radii = target;
  same_radii.spheres[2].radius_m = 0.09;
  EXPECT_THAT(CheckCalibrationTarget(same_radii)[0],
              HasSubstr("spheres[2]: its radius is within 15 mm of spheres[0]'s"));
  CalibrationTarget on_a_line = target;
  on_a_line.spheres[2].centre_T = Eigen::Vector3d(0.02, 0, -0.6);
  EXPECT_THAT(CheckCalibrationTarget(on_a_line)[0], HasSubstr("within 0.1 m of one line"));

  test::TempDir dir;
  SaveCalibrationTarget(dir / "t.yaml", target);
  const CalibrationTarget back = LoadCalibrationTarget(dir / "t.yaml");
  ASSERT_EQ(back.spheres.size(), 3u);
  EXPECT_EQ(back.spheres[2].centre_T, target.spheres[2].centre_T);
  EXPECT_EQ(back.spheres[1].radius_m, 0.08);
  SaveCalibrationTarget(dir / "bad.yaml", same_radii);
  EXPECT_THAT([&] { LoadCalibrationTarget(dir / "bad.yaml"); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("bad.yaml: spheres[2]: its radius")));
}

// One camera's view rendered here (no OpenNI2): the spheres are found and named, their
// centres within a millimetre of the truth from a single noisy frame.
TEST(FindTargetSpheresTest, FindsAndNamesEverySphereInOneNoisyView) {
  const CalibrationTarget target = DefaultCalibrationTarget();
  const RigCalibration rig = MakeRingRig({});
  const CameraCalibration& cam = rig.cameras[1];
  const auto found = FindTargetSpheres(NoisyView(cam, TargetMesh(target), 3), cam.X_RigCam, target);
  ASSERT_EQ(found.size(), 3u);
  for (const SphereSighting& s : found) {
    const Eigen::Vector3d truth =
        cam.X_RigCam.inverse() * target.spheres[static_cast<std::size_t>(s.sphere)].centre_T;
    const double error_mm = (s.centre_C - truth).norm() * 1000;
    std::printf("sphere %d: %d points, rms %.2f mm, centre off by %.2f mm, radius %.1f mm\n",
                s.sphere, s.points, s.rms_m * 1000, error_mm, s.fitted_radius_m * 1000);
    EXPECT_LT(error_mm, 1.5);
    EXPECT_GT(s.points, 1000);
  }
}

// Something round that is not the target (here an 80 mm sphere where the target has none,
// and no 80 mm sphere where it has one) is found, named by its radius, and dropped: its
// distances to the other spheres are not the target's.
TEST(FindTargetSpheresTest, DropsASphereThatDoesNotKeepTheTargetsDistances) {
  CalibrationTarget target = DefaultCalibrationTarget();
  CalibrationTarget seen = target;
  seen.spheres[1].centre_T = Eigen::Vector3d(-0.25, 0.1, -0.9);  // not where the target has it
  seen.rod_radius_m = 0;
  const RigCalibration rig = MakeRingRig({});
  const CameraCalibration& cam = rig.cameras[0];
  const auto found = FindTargetSpheres(NoisyView(cam, TargetMesh(seen), 4), cam.X_RigCam, target);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].sphere, 0);
  EXPECT_EQ(found[1].sphere, 2);
}

// The whole procedure on the virtual rig: the target hung in 3 positions (turned on the
// hook), each captured through OpenNI2 and averaged over 10 frames, the cameras' poses
// started 40 mm and 3 degrees off.
class RigCalibrationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    truth_ = MakeRingRig({});
    SaveRigCalibration(dir_ / "truth.yaml", truth_);
    ShowTarget(Eigen::Isometry3d::Identity(), 0);
    setenv("VB_VIRTUAL_SCENE", (dir_ / "scene.yaml").c_str(), 1);
  }

  // Hangs @p mesh_Rig on the hook of the virtual rig, written as @p file (a new file each
  // time, so the driver reloads it), the sensor noise drawn from @p seed.
  void Hang(const geometry::TriangleMesh& mesh_Rig, const std::string& file, std::uint64_t seed) {
    io::WriteMesh(dir_ / file, mesh_Rig);
    VirtualScene scene;
    scene.rig_path = "truth.yaml";
    scene.carcass_path = file;
    scene.floor_z_m = -2.2;
    scene.seed = seed;
    SaveVirtualScene(dir_ / "scene.yaml", scene);
  }

  // Hangs the target at @p X_RigTarget.
  void ShowTarget(const Eigen::Isometry3d& X_RigTarget, int position) {
    Hang(TargetMesh(target_, X_RigTarget), "target" + std::to_string(position) + ".ply", 5);
  }

  // What each camera of @p capture sees of the target now: 10 still frames averaged. The
  // driver picks a new scene up within 50 ms plus a render, longer on a loaded machine: the
  // capture is repeated until every camera's image differs from the last position's (up to
  // 5 times), and CaptureStillDepth restarts its average if the change lands inside it.
  std::vector<std::vector<std::uint16_t>> CaptureAfterChange(RigCapture* capture,
                                                             const RigCalibration& rig) {
    std::vector<std::vector<std::uint16_t>> depth;
    for (int attempt = 0; attempt < 5; ++attempt) {
      std::vector<StillCapture> report;
      depth = CaptureStillDepth(capture, 10, 3, 10.0, &report);
      for (std::size_t c = 0; c < depth.size(); ++c) {
        if (depth[c].empty())
          std::printf("%s: no still image (%d frames, %d restarts, %s: %s)\n",
                      rig.cameras[c].name.c_str(), report[c].frames, report[c].restarts,
                      ToString(capture->status(static_cast<int>(c)).health),
                      capture->status(static_cast<int>(c)).last_error);
      }
      bool changed = true;
      for (std::size_t c = 0; c < depth.size() && !last_.empty(); ++c) {
        const int w = rig.cameras[c].intrinsics.width, h = rig.cameras[c].intrinsics.height;
        if (depth[c].empty() || last_[c].empty()) continue;
        changed = changed && SceneMoved(MovedPixels(last_[c], depth[c], w, h), Readings(depth[c]));
      }
      if (changed) break;
      std::printf("attempt %d: the scene has not changed yet in every camera\n", attempt);
    }
    last_ = depth;
    return depth;
  }

  std::vector<std::vector<SphereSighting>> Sightings(RigCapture* capture, const RigCalibration& rig) {
    return FindTargetInViews(rig, CaptureAfterChange(capture, rig), target_);
  }

  test::TempDir dir_;
  CalibrationTarget target_ = DefaultCalibrationTarget();
  RigCalibration truth_;
  std::vector<std::vector<std::uint16_t>> last_;  // the last position's averaged images
};

TEST_F(RigCalibrationTest, RecoversPerturbedCameraPosesWithin2MmAndATenthOfADegree) {
  RigCalibration start = truth_;
  std::mt19937 rng(17);
  for (CameraCalibration& cam : start.cameras) cam.X_RigCam = Perturb(cam.X_RigCam, 40, 3, &rng);
  TargetSightings sightings;
  {
    RigCapture capture(start, CaptureOptions{});
    const double yaws[] = {0, 120, 240};
    for (int p = 0; p < 3; ++p) {
      if (p > 0) ShowTarget(Yaw(yaws[p]), p);
      sightings.push_back(Sightings(&capture, start));
      for (std::size_t c = 0; c < start.cameras.size(); ++c)
        EXPECT_GE(sightings.back()[c].size(), 2u) << "position " << p << " camera " << c;
    }
  }
  const RigSolveResult result = SolveRigCalibration(start, target_, sightings);
  double worst_mm = 0, worst_deg = 0;
  for (std::size_t c = 0; c < truth_.cameras.size(); ++c) {
    const PoseChange error = PoseDifference(truth_.cameras[c].X_RigCam, result.rig.cameras[c].X_RigCam);
    const PoseChange started = PoseDifference(truth_.cameras[c].X_RigCam, start.cameras[c].X_RigCam);
    std::printf("%s: started %.1f mm %.2f deg off; solved %.2f mm %.3f deg off; residual rms %.2f "
                "mm over %d sightings, apparent depth scale %.4f\n",
                truth_.cameras[c].name.c_str(), started.translation_m * 1000, started.rotation_deg,
                error.translation_m * 1000, error.rotation_deg, result.cameras[c].rms_mm,
                result.cameras[c].sightings, result.cameras[c].apparent_scale);
    worst_mm = std::max(worst_mm, error.translation_m * 1000);
    worst_deg = std::max(worst_deg, error.rotation_deg);
    EXPECT_LT(result.cameras[c].rms_mm, 0.4);  // measured 0.24 to 0.28 mm
  }
  // The issue asks for 2 mm and 0.2 degree. Measured over 23 runs, release and
  // AddressSanitizer builds, alone and two at once (which frames are averaged depends on the
  // machine's timing): 0.37 to 0.76 mm and 0.008 to 0.023 degree at worst.
  EXPECT_LT(worst_mm, 1.1);
  EXPECT_LT(worst_deg, 0.034);
  // The target's later positions come out as hung: turned 120 and 240 degrees on the hook.
  EXPECT_NEAR(PoseDifference(Eigen::Isometry3d::Identity(), result.X_RigTarget[1]).rotation_deg, 120, 0.2);
  EXPECT_LT(result.X_RigTarget[2].translation().norm(), 0.002);
}

TEST_F(RigCalibrationTest, CheckFlagsACameraMovedBy5MmOr1Degree) {
  const int kMoved = 2;
  struct Case {
    const char* what;
    double mm, deg;
    bool flagged;
  };
  const Case cases[] = {{"none moved", 0, 0, false}, {"5 mm", 5, 0, true}, {"1 degree", 0, 1, true}};
  std::mt19937 rng(3);
  // The check runs with the calibration the daemon holds; the rig itself (the scene) is the
  // truth, so a camera "moved" is one whose calibration no longer says where it is.
  for (const Case& k : cases) {
    RigCalibration held = truth_;
    held.cameras[kMoved].X_RigCam = Perturb(truth_.cameras[kMoved].X_RigCam, k.mm, k.deg, &rng);
    std::vector<std::vector<SphereSighting>> seen;
    last_.clear();  // the same scene in every case
    {
      RigCapture capture(held, CaptureOptions{});
      seen = Sightings(&capture, held);
    }
    const RigCheckResult check = CheckRigWithTarget(held, target_, seen);
    ASSERT_EQ(check.compared, 4) << k.what;
    for (std::size_t c = 0; c < 4; ++c) {
      const CameraCheck& cc = check.cameras[c];
      std::printf("%s: %s offset %.2f mm, turn %.3f deg%s\n", k.what, held.cameras[c].name.c_str(),
                  cc.offset_mm, cc.turn_deg, cc.moved ? " MOVED" : "");
      EXPECT_EQ(cc.moved, k.flagged && c == kMoved) << k.what << " camera " << c;
      if (c != kMoved || !k.flagged) {  // measured at most 1.06 mm and 0.040 degree
        EXPECT_LT(cc.offset_mm, 1.6) << k.what << " camera " << c;
        EXPECT_LT(cc.turn_deg, 0.06) << k.what << " camera " << c;
      }
    }
    EXPECT_EQ(check.ok, !k.flagged);
  }
}

// The saw's frame: a 40 mm ball on the saw's tool point, jogged to 5 points the saw reports
// in its own frame, each found by the rig's cameras (through OpenNI2) and paired.
TEST_F(RigCalibrationTest, SawCalibrationRecoversXSawRigFromABallTheRigSees) {
  Eigen::Isometry3d X_SawRig = Eigen::Isometry3d::Identity();
  X_SawRig.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 0.1, 1).normalized()).toRotationMatrix();
  X_SawRig.translation() = Eigen::Vector3d(1.2, -0.4, 0.9);
  CalibrationTarget ball;
  ball.spheres = {{Eigen::Vector3d::Zero(), 0.04}};
  ball.rod_radius_m = 0;
  const Eigen::Vector3d at[] = {{0.2, 0.1, -0.3}, {-0.25, 0.15, -0.6}, {0.1, -0.3, -0.9},
                                {-0.1, -0.1, -1.2}, {0.3, 0.25, -0.8}};
  std::vector<Eigen::Vector3d> p_Rig, p_Saw;
  {
    RigCapture capture(truth_, CaptureOptions{});
    for (int i = 0; i < 5; ++i) {
      Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
      X.translation() = at[i];
      Hang(TargetMesh(ball, X), "ball" + std::to_string(i) + ".ply", VirtualScene{}.seed);
      const auto depth = CaptureAfterChange(&capture, truth_);
      std::vector<Eigen::Matrix3Xd> points;
      for (std::size_t c = 0; c < truth_.cameras.size(); ++c)
        points.push_back(DepthToPoints(depth[c], truth_.cameras[c].intrinsics));
      const BallSighting seen = LocateBall(truth_, points, 0.04);
      std::printf("ball %d: %d cameras, %.2f mm from the truth, spread %.2f mm\n", i, seen.cameras,
                  (seen.centre_Rig - at[i]).norm() * 1000, seen.spread_mm);
      EXPECT_GE(seen.cameras, 2) << i;
      EXPECT_LT((seen.centre_Rig - at[i]).norm() * 1000, 0.16) << i;  // measured up to 0.10
      p_Rig.push_back(seen.centre_Rig);
      p_Saw.push_back(X_SawRig * at[i]);
    }
  }
  const SawFit fit = SolveSawCalibration(p_Rig, p_Saw);
  const PoseChange error = PoseDifference(X_SawRig.inverse(), fit.X_SawRig.inverse());
  // What matters is where a waypoint lands: the error over the region of interest's corners
  // (the saw's own origin, 1.5 m away, is off by more through the lever of a tiny turn).
  double worst_mm = 0;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p(corner & 1 ? 0.6 : -0.6, corner & 2 ? 0.6 : -0.6, corner & 4 ? 0.1 : -1.6);
    worst_mm = std::max(worst_mm, (fit.X_SawRig * p - X_SawRig * p).norm() * 1000);
  }
  std::printf("X_SawRig: residual rms %.2f mm; over the region of interest at most %.2f mm off; "
              "turned %.4f deg\n",
              fit.rms_mm, worst_mm, error.rotation_deg);
  // Measured over runs (release and AddressSanitizer builds, whose frame timing differs):
  // rms 0.03 to 0.06 mm, the region 0.09 to 0.14 mm, the turn 0.003 to 0.010 degree. The ball
  // is found far better than the target's spheres, being seen whole from four sides.
  EXPECT_LT(fit.rms_mm, 0.09);
  EXPECT_LT(worst_mm, 0.3);
  EXPECT_LT(error.rotation_deg, 0.015);
  // Checked later against a saw base that moved by 5 mm: the residuals say so.
  Eigen::Isometry3d shifted = X_SawRig;
  shifted.translation() += Eigen::Vector3d(0.005, 0, 0);
  EXPECT_GT(CheckSawCalibration(shifted, p_Rig, p_Saw).rms_mm, 4.0);
  // Points on one line cannot fix a turn about it.
  const std::vector<Eigen::Vector3d> line = {{0, 0, -0.3}, {0, 0, -0.6}, {0, 0.001, -0.9}};
  EXPECT_THAT([&] { SolveSawCalibration(line, line); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("of one line")));
}

}  // namespace
}  // namespace vb::perception
