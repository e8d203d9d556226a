#include "morph/morpher.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "geometry/mesh_measures.h"
#include "perception/carcass_generator.h"
#include "tests/support/lamb_fixture.h"

namespace vb::morph {
namespace {

using MorpherTest = test::LambTemplateTest;

// A carcass hanging upright as on the line, seen by a ring of cameras: partial and noisy.
Eigen::Matrix3Xd HangingCloud(const perception::CarcassTemplate& carcass, std::uint64_t seed,
                              perception::PosedCarcass* truth) {
  perception::PoseOptions pose;
  pose.arbitrary_orientation = false;
  *truth = perception::PoseCarcass(carcass, perception::SampleCarcassPose(seed, pose));
  perception::CloudOptions cloud;
  cloud.sigma_m = 0.004;
  cloud.missing_regions = true;
  return perception::SampleSurfaceCloud(*truth, cloud, seed + 1).points;
}

MorphOptions Upright() {
  MorphOptions options;
  options.coarse.upright.enabled = true;
  return options;
}

// The threads share the candidates' posture fits and the dense stage's two association
// ways; each writes only its own results, so the morph is the same to the last bit.
TEST_F(MorpherTest, MorphsTheSameOnOneThreadAsOnSeveral) {
  perception::PosedCarcass truth;
  const Eigen::Matrix3Xd cloud = HangingCloud(*carcass_, 4000037u, &truth);
  Morpher one(*model_, carcass_->annotations, Upright(), {.threads = 1, .worker_wrapper = {}});
  Morpher two(*model_, carcass_->annotations, Upright(), {.threads = 2, .worker_wrapper = {}});
  Morpher three(*model_, carcass_->annotations, Upright(), {.threads = 3, .worker_wrapper = {}});
  EXPECT_EQ(two.threads(), 2);
  const CarcassResult a = one.Morph(cloud, {});
  ASSERT_TRUE(a.ok) << a.error;
  // The morph is a good one (about 0.5 % of the diagonal here), so the comparison means something.
  EXPECT_LT((a.dense.mesh.V - truth.mesh.V).colwise().norm().mean() /
                geometry::BoundingBoxDiagonal(truth.mesh.V),
            0.008);
  for (Morpher* other : {&two, &three}) {
    for (int repeat = 0; repeat < 2; ++repeat) {  // and again on the same Morpher
      const CarcassResult b = other->Morph(cloud, {});
      ASSERT_TRUE(b.ok) << b.error;
      EXPECT_EQ(a.coarse.disagreement, b.coarse.disagreement);
      EXPECT_TRUE(a.coarse.mesh.V == b.coarse.mesh.V);
      EXPECT_TRUE(a.dense.mesh.V == b.dense.mesh.V);
      ASSERT_EQ(a.cuts.size(), b.cuts.size());
      for (std::size_t c = 0; c < a.cuts.size(); ++c) {
        EXPECT_TRUE(a.cuts[c].plane.point == b.cuts[c].plane.point) << a.cuts[c].name;
        EXPECT_TRUE(a.cuts[c].plane.normal == b.cuts[c].plane.normal) << a.cuts[c].name;
        EXPECT_EQ(a.cuts[c].confidence, b.cuts[c].confidence) << a.cuts[c].name;
      }
    }
  }
}

// The deadline reaches the solves on every thread: a cancelled morph stops early and says so.
TEST_F(MorpherTest, StopsOnEveryThreadWhenCancelled) {
  perception::PosedCarcass truth;
  const Eigen::Matrix3Xd cloud = HangingCloud(*carcass_, 4000037u, &truth);
  Morpher morpher(*model_, carcass_->annotations, Upright());
  const CarcassResult full = morpher.Morph(cloud, {});
  ASSERT_TRUE(full.ok) << full.error;
  std::atomic<bool> cancel{true};
  MorphDeadline deadline;
  deadline.cancel = &cancel;
  const CarcassResult stopped = morpher.Morph(cloud, {}, deadline);
  EXPECT_FALSE(stopped.ok);
  EXPECT_NE(stopped.error.find("abandoned"), std::string::npos) << stopped.error;
  EXPECT_LT(stopped.seconds, 0.5 * full.seconds);
  // The deadline was this morph's only: the next one runs to the end.
  EXPECT_TRUE(morpher.Morph(cloud, {}).ok);
}

TEST_F(MorpherTest, SaysWhyOnABadTargetAndGoesOn) {
  Morpher morpher(*model_, carcass_->annotations, Upright());
  const CarcassResult few = morpher.Morph(Eigen::Matrix3Xd::Random(3, 5), {});
  EXPECT_FALSE(few.ok);
  EXPECT_NE(few.error.find("5 points"), std::string::npos) << few.error;
  Eigen::Matrix3Xd nan = Eigen::Matrix3Xd::Random(3, 2000);
  nan(1, 700) = std::numeric_limits<double>::quiet_NaN();
  const CarcassResult bad = morpher.Morph(nan, {});
  EXPECT_FALSE(bad.ok);
  EXPECT_FALSE(bad.error.empty());
}

}  // namespace
}  // namespace vb::morph
