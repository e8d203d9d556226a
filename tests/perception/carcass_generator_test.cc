#include "perception/carcass_generator.h"

#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "geometry/plane_cut.h"
#include "perception/virtual_rig.h"

namespace vb::perception {
namespace {

class CarcassTemplateTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dut_ = new CarcassTemplate(BuildCarcassTemplate()); }
  static void TearDownTestSuite() {
    delete dut_;
    dut_ = nullptr;
  }
  static const CarcassTemplate& dut() { return *dut_; }

 private:
  static CarcassTemplate* dut_;
};
CarcassTemplate* CarcassTemplateTest::dut_ = nullptr;

double Sum(const std::vector<geometry::PartMeasure>& parts) {
  double sum = 0.0;
  for (const geometry::PartMeasure& p : parts) sum += p.volume;
  return sum;
}

TEST_F(CarcassTemplateTest, IsAWatertightOrientedManifoldOfLambSize) {
  const geometry::TriangleMesh& mesh = dut().mesh;
  const geometry::TopologyReport topology = geometry::AnalyzeTopology(mesh);
  EXPECT_TRUE(topology.is_closed_manifold()) << topology.Describe();
  EXPECT_TRUE(topology.is_consistently_oriented()) << topology.Describe();
  EXPECT_EQ(topology.components, 1);
  EXPECT_EQ(topology.euler_characteristic(), 2) << "a carcass has no handles";
  EXPECT_GE(mesh.num_vertices(), 5000);
  EXPECT_LE(mesh.num_vertices(), 10000);
  const double length = mesh.V.row(2).maxCoeff() - mesh.V.row(2).minCoeff();
  EXPECT_GE(length, 1.0);
  EXPECT_LE(length, 1.3);
  // A dressed lamb carcass weighs roughly 15-30 kg at about 1 kg per litre.
  EXPECT_GT(geometry::SignedVolume(mesh), 0.015);
  EXPECT_LT(geometry::SignedVolume(mesh), 0.035);
  ASSERT_TRUE(mesh.has_normals());
  EXPECT_NEAR(mesh.N.colwise().norm().minCoeff(), 1.0, 1e-9);
}

TEST_F(CarcassTemplateTest, HangsFromTheHindLegs) {
  const geometry::TriangleMesh& mesh = dut().mesh;
  Eigen::Index top = 0, bottom = 0;
  mesh.V.row(2).maxCoeff(&top);
  mesh.V.row(2).minCoeff(&bottom);
  EXPECT_GT(dut().weights(kShankLeft, top) + dut().weights(kShankRight, top), 0.99)
      << "the highest point is a hock";
  EXPECT_GT(dut().weights(kForearmLeft, bottom) + dut().weights(kForearmRight, bottom) +
                dut().weights(kNeck, bottom),
            0.99);
}

TEST_F(CarcassTemplateTest, SkinWeightsArePartitionsOfUnity) {
  const auto& w = dut().weights;
  EXPECT_GE(w.minCoeff(), 0.0);
  EXPECT_LT((w.colwise().sum().array() - 1.0).abs().maxCoeff(), 1e-12);
}

TEST_F(CarcassTemplateTest, ThreeCutsOrderedAlongTheSpineEachOneClosedLoop) {
  const io::Annotations& a = dut().annotations;
  ASSERT_EQ(a.cuts.size(), 3u);
  EXPECT_EQ(a.parts, (std::vector<std::string>{"leg", "loin", "rack", "shoulder"}));
  EXPECT_EQ(a.vertex_count, dut().mesh.num_vertices());
  EXPECT_EQ(a.face_count, dut().mesh.num_faces());
  for (std::size_t c = 0; c < a.cuts.size(); ++c) {
    const io::CutAnnotation& cut = a.cuts[c];
    const auto loops = geometry::PlaneSection(dut().mesh, cut.plane);
    ASSERT_EQ(loops.size(), 1u) << cut.name;
    EXPECT_TRUE(loops[0].closed) << cut.name;
    EXPECT_GE(cut.line.size(), 20u) << cut.name;
    for (const geometry::SurfacePoint& p : cut.line) {
      EXPECT_NEAR(cut.plane.SignedDistance(geometry::Evaluate(dut().mesh, p)), 0.0, 1e-12);
    }
    if (c > 0) {
      // Each cut lies below the previous one, seen from the gambrel.
      EXPECT_LT(a.cuts[c - 1].plane.SignedDistance(cut.plane.point), -0.05) << cut.name;
    }
  }
}

TEST_F(CarcassTemplateTest, CutsSplitTheCarcassIntoFourPartsThatSumToTheWhole) {
  const auto parts = geometry::MeasureParts(dut().mesh, dut().annotations.planes());
  ASSERT_EQ(parts.size(), 4u);
  const double total = geometry::SignedVolume(dut().mesh);
  for (const geometry::PartMeasure& p : parts) EXPECT_GT(p.volume, 0.05 * total);
  EXPECT_NEAR(Sum(parts), total, 1e-9 * total);
}

TEST_F(CarcassTemplateTest, RestPoseReproducesTheTemplate) {
  const PosedCarcass rest = PoseCarcass(dut(), CarcassPose{});
  EXPECT_LT((rest.mesh.V - dut().mesh.V).cwiseAbs().maxCoeff(), 1e-12);
  for (std::size_t c = 0; c < rest.cut_planes.size(); ++c) {
    EXPECT_LT((rest.cut_planes[c].normal - dut().annotations.cuts[c].plane.normal).norm(), 1e-12);
  }
}

class CarcassTargetTest : public CarcassTemplateTest,
                          public ::testing::WithParamInterface<std::uint64_t> {};

TEST_P(CarcassTargetTest, KeepsConnectivityAndGroundTruthIsConsistent) {
  const CarcassPose pose = SampleCarcassPose(GetParam());
  EXPECT_GE(pose.global_scale, 0.8);
  EXPECT_LE(pose.global_scale, 1.2);
  const PosedCarcass target = PoseCarcass(dut(), pose);
  ASSERT_EQ(target.mesh.F, dut().mesh.F);
  const geometry::TopologyReport topology = geometry::AnalyzeTopology(target.mesh);
  EXPECT_TRUE(topology.is_closed_manifold() && topology.is_consistently_oriented())
      << topology.Describe();
  const double volume = geometry::SignedVolume(target.mesh);
  EXPECT_GT(volume, 0.0);

  ASSERT_EQ(target.cut_planes.size(), 3u);
  for (std::size_t c = 0; c < 3; ++c) {
    const geometry::Plane& plane = target.cut_planes[c];
    // The template's cut line, carried by vertex correspondence, lies on the true plane...
    EXPECT_LT(target.cut_line_rms_m[c], 1e-9) << "cut " << c;
    // ...which meets the target in exactly one closed loop.
    const auto loops = geometry::PlaneSection(target.mesh, plane);
    ASSERT_EQ(loops.size(), 1u) << "cut " << c;
    EXPECT_TRUE(loops[0].closed);
    EXPECT_GT(plane.normal.dot(target.up_world), 0.8) << "a cut stays roughly across the spine";
    if (c > 0) {
      EXPECT_LT(target.cut_planes[c - 1].SignedDistance(plane.point), 0.0)
          << "cuts keep their order";
    }
  }
  const auto parts = geometry::MeasureParts(target.mesh, target.cut_planes);
  for (const geometry::PartMeasure& p : parts) EXPECT_GT(p.volume, 0.05 * volume);
  EXPECT_NEAR(Sum(parts), volume, 1e-9 * volume);
}

TEST_P(CarcassTargetTest, UprightPlacementHangsAlongPlusZ) {
  PoseOptions options;
  options.arbitrary_orientation = false;
  const PosedCarcass target = PoseCarcass(dut(), SampleCarcassPose(GetParam(), options));
  EXPECT_GT(target.up_world.z(), 0.95);
}

INSTANTIATE_TEST_SUITE_P(Seeds, CarcassTargetTest,
                         ::testing::Values(1u, 2u, 3u, 5u, 8u, 13u, 21u, 34u, 1000003u));

TEST_F(CarcassTemplateTest, PosesAreDeterministicPerSeedAndDifferAcrossSeeds) {
  const PosedCarcass a = PoseCarcass(dut(), SampleCarcassPose(42));
  const PosedCarcass b = PoseCarcass(dut(), SampleCarcassPose(42));
  const PosedCarcass c = PoseCarcass(dut(), SampleCarcassPose(43));
  EXPECT_EQ(a.mesh.V, b.mesh.V);
  EXPECT_GT((a.mesh.V - c.mesh.V).cwiseAbs().maxCoeff(), 0.01);
}

// A joint's angles are drawn in a fixed order (the last axis first), whatever order the
// compiler evaluates a call's arguments in: the lambs every benchmark was drawn from.
TEST_F(CarcassTemplateTest, AJointsAnglesAreDrawnLastAxisFirst) {
  std::mt19937_64 rng(42);
  const auto uniform = [&rng](double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
  };
  uniform(-25, 25);  // the twist on the hook
  const double z = uniform(-6, 6), y = uniform(-5, 5), x = uniform(-8, 8);
  const auto radians = [](double degrees) { return degrees * std::numbers::pi / 180.0; };
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(radians(z), Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(radians(y), Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(radians(x), Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  EXPECT_TRUE(SampleCarcassPose(42).bones[kLumbar].rotation.isApprox(expected, 1e-15));
}

// Seed 42 as every benchmark's lambs were drawn: a draw moved anywhere in SampleCarcassPose
// (a joint, a side, the placement) changes these values, recorded from the GCC build of the
// code before the draws were named (docs/decisions.md).
TEST_F(CarcassTemplateTest, TheDrawsGiveTheLambsTheBenchmarksWereRunOn) {
  const CarcassPose pose = SampleCarcassPose(42);
  const auto row = [](const Eigen::Matrix3d& R, int r) { return Eigen::Vector3d(R.row(r)); };
  const auto near = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return (a - b).norm() < 1e-12;
  };
  EXPECT_EQ(pose.global_scale, 0.99671462721428261);
  const Eigen::Matrix3d& thigh_left = pose.bones[kThighLeft].rotation;
  const Eigen::Matrix3d& thigh_right = pose.bones[kThighRight].rotation;
  const Eigen::Matrix3d& arm_left = pose.bones[kUpperArmLeft].rotation;
  const Eigen::Matrix3d& arm_right = pose.bones[kUpperArmRight].rotation;
  EXPECT_TRUE(near(row(thigh_left, 0),
                   {0.99923291370182366, -0.0066334758090451649, 0.038595092611037787}));
  EXPECT_TRUE(near(row(thigh_left, 1), {0.0, 0.98554912835055042, 0.16938983324707027}));
  EXPECT_TRUE(near(row(thigh_right, 0),
                   {0.99708041854374529, -0.0049348138822651964, -0.076198993225482958}));
  EXPECT_TRUE(near(row(thigh_right, 1), {0.0, 0.99790950278627055, -0.064626807509408996}));
  EXPECT_TRUE(
      near(row(arm_left, 0), {0.99166512936779494, -0.028239709059988499, -0.12570914854600551}));
  EXPECT_TRUE(near(row(arm_left, 1), {0.0, 0.97568424740499216, -0.21918085994391481}));
  EXPECT_TRUE(
      near(row(arm_right, 0), {0.9994279614328575, -0.013029233081065031, 0.031208796700321641}));
  EXPECT_TRUE(near(row(arm_right, 1), {0.0, 0.92280829232620587, 0.38525946531395155}));
  EXPECT_TRUE(near(row(pose.X_WorldBody.linear(), 0),
                   {-0.017313181602597094, -0.98511846748479992, 0.17100251098505748}));
  EXPECT_TRUE(near(pose.X_WorldBody.translation(),
                   {-0.19451534156763844, 0.2637978380115632, -0.13512899426691721}));
}

// angle_scale widens the joints' ranges and nothing else: the same seed draws the same
// proportions and placement; at 0 every joint is straight.
TEST_F(CarcassTemplateTest, TheAngleScaleTurnsTheJointsAndNothingElse) {
  PoseOptions line, wide, straight;
  wide.angle_scale = 2.5;
  straight.angle_scale = 0.0;
  const CarcassPose a = SampleCarcassPose(42, line);
  const CarcassPose b = SampleCarcassPose(42, wide);
  const CarcassPose c = SampleCarcassPose(42, straight);
  EXPECT_EQ(a.global_scale, b.global_scale);
  EXPECT_TRUE(a.X_WorldBody.isApprox(b.X_WorldBody, 0.0));
  double turned_more = 0;
  for (int bone = 0; bone < kNumBones; ++bone) {
    const auto k = static_cast<std::size_t>(bone);
    EXPECT_EQ(a.bones[k].length_scale, b.bones[k].length_scale);
    EXPECT_EQ(a.bones[k].girth_scale, b.bones[k].girth_scale);
    EXPECT_EQ(a.bones[k].fat_m, b.bones[k].fat_m);
    EXPECT_TRUE(c.bones[k].rotation.isApprox(Eigen::Matrix3d::Identity(), 1e-15)) << bone;
    const auto angle = [](const Eigen::Matrix3d& R) { return Eigen::AngleAxisd(R).angle(); };
    turned_more += angle(b.bones[k].rotation) - angle(a.bones[k].rotation);
  }
  EXPECT_GT(turned_more, 0.0);
}

// The rig's carcasses take the angle scale too (bench --pose-scale): the same seed in wider
// joints, still hung with the gambrel end at z = 0.
TEST_F(CarcassTemplateTest, HangingCarcassesTakeTheAngleScale) {
  const PosedCarcass line = HangCarcass(dut(), 42);
  const PosedCarcass same = HangCarcass(dut(), 42, 1.0);
  const PosedCarcass wide = HangCarcass(dut(), 42, 2.5);
  EXPECT_EQ(line.mesh.V, same.mesh.V);
  EXPECT_GT((line.mesh.V - wide.mesh.V).colwise().norm().maxCoeff(), 0.05);
  for (const PosedCarcass* c : {&line, &wide}) EXPECT_NEAR(c->mesh.V.row(2).maxCoeff(), 0.0, 1e-12);
}

TEST_F(CarcassTemplateTest, NormalNoiseFollowsThePaperProtocol) {
  const double sigma = 0.004;
  const geometry::TriangleMesh noisy = AddNormalNoise(dut().mesh, sigma, 7);
  ASSERT_EQ(noisy.F, dut().mesh.F);
  const Eigen::Matrix3Xd d = noisy.V - dut().mesh.V;
  const Eigen::VectorXd along = (d.array() * dut().mesh.N.array()).colwise().sum().transpose();
  const double n = static_cast<double>(along.size());
  const double mean = along.mean();
  const double stddev = std::sqrt((along.array() - mean).square().sum() / (n - 1));
  EXPECT_NEAR(mean, 0.0, 4 * sigma / std::sqrt(n));
  EXPECT_NEAR(stddev, sigma, 0.05 * sigma);
  // Only along the normal.
  EXPECT_LT((d - dut().mesh.N * along.asDiagonal()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(AddNormalNoise(dut().mesh, 0.0, 7).V, dut().mesh.V);
}

TEST_F(CarcassTemplateTest, CloudsSampleTheSurfaceAndMissRegionsOnRequest) {
  const PosedCarcass target = PoseCarcass(dut(), SampleCarcassPose(5));
  CloudOptions options;
  options.num_points = 5000;
  options.sigma_m = 0.002;
  const geometry::PointCloud full = SampleSurfaceCloud(target, options, 1);
  EXPECT_EQ(full.size(), 5000);
  EXPECT_FALSE(full.has_normals());
  // Every sample is near the surface: within an edge length plus 6 sigma of a vertex.
  for (int i = 0; i < full.size(); i += 7) {
    const double nearest =
        (target.mesh.V.colwise() - full.points.col(i)).colwise().norm().minCoeff();
    EXPECT_LT(nearest, 0.03 + 6 * options.sigma_m);
  }
  options.missing_regions = true;
  const geometry::PointCloud partial = SampleSurfaceCloud(target, options, 1);
  EXPECT_LT(partial.size(), full.size());
  EXPECT_GT(partial.size(), full.size() / 2);
}

}  // namespace
}  // namespace vb::perception
