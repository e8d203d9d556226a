#include "morph/coarse_alignment.h"

#include <gtest/gtest.h>

#include "io/mesh_measures.h"
#include "perception/carcass_generator.h"
#include "tests/support/lamb_fixture.h"

namespace vb::morph {
namespace {

using CoarseAlignmentTest = test::LambTemplateTest;

TEST_F(CoarseAlignmentTest, AlignsPostureOfPlacedAndPosedCarcasses) {
  // Several poses, scales and placements; noise as a camera would add.
  for (std::uint64_t seed : {1000003u, 1000004u, 1000008u}) {
    const perception::PosedCarcass truth =
        perception::PoseCarcass(*carcass_, perception::SampleCarcassPose(seed));
    const Eigen::Matrix3Xd target = perception::AddNormalNoise(truth.mesh, 0.004, seed).V;
    const CoarseResult r = AlignCoarse(*model_, target);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.mesh.F, model_->mesh.F);
    const double diagonal = io::BoundingBoxDiagonal(truth.mesh.V);
    const double mean_error = (r.mesh.V - truth.mesh.V).colwise().norm().mean() / diagonal;
    EXPECT_LT(mean_error, 0.04) << "seed " << seed;
    // Without the right association, the carcass would be far off (upside down: ~40 %).
    EXPECT_GE(r.association.terminals.size(), 3u);
  }
}

TEST_F(CoarseAlignmentTest, ReportsBadTargetsInsteadOfThrowing) {
  CoarseResult r = AlignCoarse(*model_, Eigen::Matrix3Xd::Random(3, 20));
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("fewer than 50"), std::string::npos);
  Eigen::Matrix3Xd nan = Eigen::Matrix3Xd::Random(3, 500);
  nan(1, 7) = std::nan("");
  r = AlignCoarse(*model_, nan);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("non-finite"), std::string::npos);
  r = AlignCoarse(*model_, Eigen::Matrix3Xd::Zero(3, 500));
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.error.empty());
}

}  // namespace
}  // namespace vb::morph
