#include "daemon/job.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "io/lcm_publisher.h"

namespace vb::daemon {
namespace {

using ::testing::HasSubstr;

// A result with two horizontal cuts, lines as circles of radius 0.1 m around the z axis.
morph::CarcassResult TwoCuts(double confidence0, double confidence1) {
  morph::CarcassResult r;
  r.ok = true;
  for (const auto& [name, z, confidence] :
       {std::tuple{"leg_loin", -0.4, confidence0}, std::tuple{"loin_rack", -0.6, confidence1}}) {
    morph::TransferredCut cut;
    cut.name = name;
    cut.plane.point = Eigen::Vector3d(0, 0, z);
    cut.plane.normal = Eigen::Vector3d::UnitZ();
    cut.confidence = confidence;
    cut.coverage = 0.9;
    for (int i = 0; i < 200; ++i) {
      const double a = 2 * M_PI * i / 200;
      cut.line.emplace_back(0.1 * std::cos(a), 0.1 * std::sin(a), z + 0.002 * std::sin(7 * a));
    }
    r.cuts.push_back(cut);
  }
  r.parts = {{1e-3, 0.1}, {2e-3, 0.2}, {3e-3, 0.3}};
  return r;
}

TEST(JobTest, WaypointsLieOnTheCutPlanesInTheSawFrame) {
  Eigen::Isometry3d X_SawRig = Eigen::Isometry3d::Identity();
  X_SawRig.translation() = Eigen::Vector3d(0.2, 0, 1.8);
  io::saw::Job job;
  EXPECT_EQ(MakeSawJob(TwoCuts(0.9, 0.8), X_SawRig, 0.6, 17, 3, &job), "");
  EXPECT_EQ(job.carcass_id, 17u);
  EXPECT_EQ(job.job_sequence, 3);
  ASSERT_EQ(job.num_cuts, 2);
  EXPECT_EQ(job.cuts[0].num_waypoints, io::saw::kMaxWaypoints);
  EXPECT_EQ(job.cuts[1].confidence_percent, 80);
  for (int i = 0; i < job.cuts[1].num_waypoints; ++i) {
    const Eigen::Vector3d& p = job.cuts[1].waypoints[static_cast<std::size_t>(i)];
    EXPECT_NEAR(p.z(), 1.8 - 0.6, 1e-12);  // projected onto the plane, then into the saw frame
    EXPECT_NEAR((p - Eigen::Vector3d(0.2, 0, p.z())).norm(), 0.1, 1e-3);
  }
  std::array<io::saw::Frame, io::saw::kMaxJobFrames> frames;
  io::saw::Protector protector;
  EXPECT_EQ(io::saw::EncodeJob(job, &protector, &frames), 2 + 2 * (1 + io::saw::kMaxWaypoints));
}

TEST(JobTest, RefusesUntrustedOrUnsendableJobsSayingWhy) {
  io::saw::Job job;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  EXPECT_THAT(MakeSawJob(TwoCuts(0.9, 0.5), I, 0.6, 1, 1, &job),
              HasSubstr("cut loin_rack confidence 0.50 is below 0.60"));
  morph::CarcassResult nan = TwoCuts(std::nan(""), 0.9);
  EXPECT_THAT(MakeSawJob(nan, I, 0.6, 1, 1, &job), HasSubstr("cut leg_loin confidence"));
  Eigen::Isometry3d far = I;
  far.translation() = Eigen::Vector3d(5, 0, 0);  // beyond the protocol's +-3.2767 m
  EXPECT_THAT(MakeSawJob(TwoCuts(0.9, 0.9), far, 0.6, 1, 1, &job), HasSubstr("outside the saw protocol's range"));
  morph::CarcassResult failed;
  failed.error = "coarse stage: no skeleton";
  EXPECT_THAT(MakeSawJob(failed, I, 0.6, 1, 1, &job), HasSubstr("morph failed: coarse stage"));
}

TEST(JobTest, CutLinesMessagePassesThePublishersChecks) {
  io::Annotations annotations;
  annotations.parts = {"leg", "loin", "rack"};
  const JobIdentity id{"C000042", 42, "lamb", 2, 1700000000000000};
  vbutcher::cut_lines_t m = MakeCutLines(TwoCuts(0.9, 0.8), annotations, id);
  EXPECT_EQ(io::ValidateCutLines(m), "");
  EXPECT_EQ(m.carcass_id, "C000042");
  EXPECT_EQ(m.num_cuts, 2);
  EXPECT_LE(m.cuts[0].num_points, io::kMaxLinePointsPerCut);
  EXPECT_EQ(m.num_parts, 3);
  EXPECT_EQ(m.parts[2].name, "rack");
  morph::CarcassResult failed;
  failed.error = "dense stage: diverged";
  m = MakeCutLines(failed, annotations, id);
  EXPECT_EQ(io::ValidateCutLines(m), "");
  EXPECT_EQ(m.num_cuts, 0);
  EXPECT_EQ(m.status, "dense stage: diverged");
}

}  // namespace
}  // namespace vb::daemon
