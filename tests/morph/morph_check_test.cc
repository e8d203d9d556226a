#include "morph/morph_check.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "geometry/mesh_measures.h"
#include "geometry/rotation.h"
#include "morph/morph_carcass.h"
#include "perception/carcass_generator.h"
#include "tests/support/lamb_fixture.h"

namespace vb::morph {
namespace {

class MorphCheckTest : public test::LambTemplateTest {
 protected:
  // As on the line: the carcass hangs hind legs up (+z), as the template does.
  static MorphOptions Upright() {
    MorphOptions options;
    options.coarse.upright.enabled = true;
    return options;
  }
  static CarcassResult MorphUpright(const Eigen::Matrix3Xd& cloud) {
    return MorphCarcass(*model_, carcass_->annotations, cloud, {}, Upright());
  }
};

// The reach of a right morph of a lamb cloud with 3 mm noise, template sizes (measured
// 0.0087).
constexpr double kGoodReach = 0.013;

double MeanErrorRelative(const CarcassResult& r, const perception::PosedCarcass& truth) {
  return (r.dense.mesh.V - truth.mesh.V).colwise().norm().mean() /
         geometry::BoundingBoxDiagonal(truth.mesh.V);
}

TEST_F(MorphCheckTest, TrustsAGoodMorphAndDistrustsAnUpsideDownOne) {
  int wrong_morphs = 0;
  for (std::uint64_t seed : {2000003u, 2000011u}) {
    perception::PosedCarcass truth;
    const Eigen::Matrix3Xd cloud = test::HangingCloud(*carcass_, seed, 0.003, &truth);

    const CarcassResult good = MorphUpright(cloud);  // the truth: hind legs up
    ASSERT_TRUE(good.ok) << good.error;
    EXPECT_LT(MeanErrorRelative(good, truth), 0.02) << "seed " << seed;
    EXPECT_GT(good.check.confidence, 0.9) << "seed " << seed << ": " << good.check.concern;
    for (const TransferredCut& cut : good.cuts) EXPECT_GT(cut.confidence, 0.6) << cut.name;

    // Force the wrong answer: tell the coarse stage the carcass hangs head up. Whatever it
    // then makes of the cloud is wrong, and the check must say so without ground truth.
    MorphOptions flipped;
    flipped.coarse.upright = {.enabled = true, .target_up = -Eigen::Vector3d::UnitZ()};
    const CarcassResult wrong = MorphCarcass(*model_, carcass_->annotations, cloud, {}, flipped);
    if (!wrong.ok) continue;  // no such placement among the candidates: nothing to send
    ++wrong_morphs;
    EXPECT_GT(MeanErrorRelative(wrong, truth), 0.05) << "seed " << seed;
    // Measured 0.038 and 0.031 (the daemon sends from 0.6).
    EXPECT_LT(wrong.check.confidence, 0.14) << "seed " << seed;
    EXPECT_FALSE(wrong.check.concern.empty());
    for (const TransferredCut& cut : wrong.cuts) EXPECT_LT(cut.confidence, 0.6) << cut.name;
  }
  EXPECT_GE(wrong_morphs, 1) << "no wrong morph was made, so the check was not tested";
}

// A cloud in millimetres (or in the 100 um units some recorders write) read as metres is
// morphed as well as one in metres, 1000 or 10 times larger. No sign of a bad fit shows it;
// the size does.
TEST_F(MorphCheckTest, DistrustsATargetInOtherUnits) {
  const Eigen::Matrix3Xd cloud = test::HangingCloud(*carcass_, 2000003u, 0.003);
  const CarcassResult metres = MorphUpright(cloud);
  ASSERT_TRUE(metres.ok) << metres.error;
  // Measured 0.871: this lamb is small (the synthetic ones are 0.8 to 1.2 times the template).
  EXPECT_NEAR(metres.check.size, 0.872, 0.02);
  EXPECT_GT(metres.check.confidence, 0.9) << metres.check.concern;

  for (const double units : {10.0, 1000.0, 0.01}) {
    const CarcassResult scaled = MorphUpright(units * cloud);
    ASSERT_TRUE(scaled.ok) << units << ": " << scaled.error;
    EXPECT_NEAR(scaled.check.size / metres.check.size, units, 0.05 * units);
    EXPECT_EQ(scaled.check.confidence, 0.0) << units;
    EXPECT_NE(scaled.check.concern.find("times the template's size"), std::string::npos)
        << scaled.check.concern;
    for (const TransferredCut& cut : scaled.cuts) EXPECT_EQ(cut.confidence, 0.0) << cut.name;
  }
}

// A part of the carcass the morph left uncovered (points beyond the body, as a limb the
// template put elsewhere would leave) is read by how far it lies, once it holds more than 1 %
// of the points, and nothing is sent; a smaller one leaves the reach and the confidence as
// they were.
TEST_F(MorphCheckTest, ReachReadsHowFarTheUncoveredPartLies) {
  const Eigen::Matrix3Xd cloud = test::HangingCloud(*carcass_, 2000003u, 0.003);
  const CarcassResult good = MorphUpright(cloud);
  ASSERT_TRUE(good.ok) << good.error;
  const double size = good.coarse.association.from_to.scale;
  EXPECT_LT(good.check.reach, kGoodReach) << "measured " << good.check.reach;

  const Eigen::Vector3d beyond =
      good.dense.target.rowwise().maxCoeff() + Eigen::Vector3d(0.3 * size, 0.0, 0.0);
  double nearest = std::numeric_limits<double>::infinity();
  for (Eigen::Index v = 0; v < good.dense.mesh.V.cols(); ++v)
    nearest = std::min(nearest, (good.dense.mesh.V.col(v) - beyond).norm());
  const Eigen::Index n = good.dense.target.cols();
  for (const Eigen::Index extra : {n / 50, n / 200}) {  // 2 % and 0.5 % of the points
    DenseResult uncovered = good.dense;
    uncovered.target.conservativeResize(3, n + extra);
    uncovered.target.rightCols(extra).colwise() = beyond;
    const MorphCheck check = CheckMorph(*model_, good.coarse, uncovered);
    if (extra > n / 100) {
      EXPECT_NEAR(check.reach, nearest / size, 1e-9);
      EXPECT_EQ(check.confidence, 0.0);
      EXPECT_NE(check.concern.find("farthest 1 % of the target"), std::string::npos)
          << check.concern;
    } else {
      EXPECT_LT(check.reach, kGoodReach) << extra << " points";
      EXPECT_GT(check.confidence, 0.9) << check.concern;
    }
    EXPECT_NEAR(check.unexplained,
                (good.check.unexplained * static_cast<double>(n) + static_cast<double>(extra)) /
                    static_cast<double>(n + extra),
                1e-12);
  }
}

// The reach counts from what the noise and the template's vertex spacing explain, and the
// confidence falls linearly over [reach_start, reach_end] beyond that; a reach that cannot be
// read sends nothing.
TEST_F(MorphCheckTest, ReachCountsBeyondTheNoiseAndTheVertexSpacing) {
  const Eigen::Matrix3Xd cloud = test::HangingCloud(*carcass_, 2000003u, 0.003);
  const CarcassResult good = MorphUpright(cloud);
  ASSERT_TRUE(good.ok) << good.error;
  EXPECT_EQ(good.check.noise, good.dense.noise);
  double edges = 0.0;
  int count = 0;
  for (Eigen::Index f = 0; f < model_->mesh.F.cols(); ++f) {
    for (int e = 0; e < 3; ++e) {
      const int a = model_->mesh.F(e, f), b = model_->mesh.F((e + 1) % 3, f);
      if (a < b) {
        edges += (model_->V.col(a) - model_->V.col(b)).norm();
        ++count;
      }
    }
  }
  const MorphCheckOptions defaults;
  EXPECT_NEAR(good.check.reach_allowance,
              defaults.reach_noise * good.dense.noise + edges / count / std::sqrt(3.0), 1e-12);
  // A right morph of a cloud with 3 mm noise reads within its allowance (measured 0.0049
  // under it: the noise and the spacing add less than their sum).
  EXPECT_LT(good.check.reach - good.check.reach_allowance, -0.0033);

  // The reach beyond the allowance halfway along the ramp halves the confidence.
  MorphCheckOptions off = defaults, halfway = defaults;
  off.reach_start = 1.0;
  off.reach_end = 2.0;
  const double beyond = good.check.reach - good.check.reach_allowance;
  halfway.reach_start = beyond - 0.01;
  halfway.reach_end = beyond + 0.01;
  const double without = CheckMorph(*model_, good.coarse, good.dense, off).confidence;
  ASSERT_GT(without, 0.9);
  // Within its allowance the reach leaves the confidence as it was (no factor above 1).
  EXPECT_EQ(CheckMorph(*model_, good.coarse, good.dense, defaults).confidence, without);
  EXPECT_NEAR(CheckMorph(*model_, good.coarse, good.dense, halfway).confidence, 0.5 * without,
              1e-9);
  // The same cloud read noisier: the allowance grows with the noise, and moves the reach off
  // the ramp, below its start.
  DenseResult noisier = good.dense;
  noisier.noise += 0.01;
  const MorphCheck read_noisier = CheckMorph(*model_, good.coarse, noisier, halfway);
  EXPECT_NEAR(read_noisier.reach_allowance - good.check.reach_allowance,
              defaults.reach_noise * 0.01, 1e-12);
  EXPECT_EQ(read_noisier.confidence, CheckMorph(*model_, good.coarse, noisier, off).confidence);

  // No target points: nothing shows the morph covers the target, and nothing is sent.
  DenseResult empty = good.dense;
  empty.target.resize(3, 0);
  const MorphCheck unread = CheckMorph(*model_, good.coarse, empty);
  EXPECT_TRUE(std::isnan(unread.reach));
  EXPECT_EQ(unread.confidence, 0.0);
  EXPECT_EQ(unread.concern, "no target points to check the morph against");
}

// The ambiguity compares the chosen placement with the runner-up as both stood when the
// choice was made; the chosen one's fit goes on after that, and its lower disagreement then
// must not read as a clearer choice.
TEST_F(MorphCheckTest, AmbiguityComparesBothPlacementsWhenTheChoiceWasMade) {
  const Eigen::Matrix3Xd cloud = test::HangingCloud(*carcass_, 2000003u, 0.003);
  const CarcassResult good = MorphUpright(cloud);
  ASSERT_TRUE(good.ok) << good.error;
  const CoarseResult& coarse = good.coarse;
  ASSERT_TRUE(std::isfinite(coarse.runner_up_disagreement));
  EXPECT_EQ(good.check.ambiguity, coarse.choice_disagreement / coarse.runner_up_disagreement);
  EXPECT_LT(coarse.choice_disagreement, coarse.runner_up_disagreement);
  // The choice's scores are weighted by the template's asymmetry; read unweighted, the
  // posture fit's remaining rounds lowered the chosen placement's disagreement.
  MorphOptions unweighted = Upright();
  unweighted.coarse.choice_by_asymmetry = false;
  const CarcassResult plain = MorphCarcass(*model_, carcass_->annotations, cloud, {}, unweighted);
  ASSERT_TRUE(plain.ok) << plain.error;
  EXPECT_NE(plain.coarse.choice_disagreement, coarse.choice_disagreement);
  EXPECT_LT(plain.coarse.disagreement, plain.coarse.choice_disagreement);
  // The placements compared, as reports and the shape benchmark read them: the chosen one
  // (turned 0 degrees from the placement kept) scored choice_disagreement, and the least score
  // of those turned distinct_angle_deg or more from it is the runner-up's.
  ASSERT_GE(coarse.choices.size(), 2u);
  const double distinct_deg = Upright().coarse.distinct_angle_deg;
  int chosen = 0;
  double runner_up = std::numeric_limits<double>::infinity();
  for (const PlacementChoice& p : coarse.choices) {
    const double deg = geometry::RotationAngleDeg(p.R * coarse.placement.R.transpose());
    EXPECT_GE(p.disagreement, coarse.choice_disagreement);
    if (p.R == coarse.placement.R) {  // the chosen one: a copy of the placement
      ++chosen;
      EXPECT_EQ(p.disagreement, coarse.choice_disagreement);
    }
    if (deg > distinct_deg) runner_up = std::min(runner_up, p.disagreement);
  }
  EXPECT_EQ(chosen, 1);
  EXPECT_EQ(runner_up, coarse.runner_up_disagreement);

  // Chosen rigidly (no posture fit before the choice): the same ratio, of the rigid fits.
  MorphOptions rigid = Upright();
  rigid.coarse.articulated_candidates = 0;
  const CarcassResult by_rigid_fits =
      MorphCarcass(*model_, carcass_->annotations, cloud, {}, rigid);
  ASSERT_TRUE(by_rigid_fits.ok) << by_rigid_fits.error;
  EXPECT_GT(by_rigid_fits.coarse.choice_disagreement, 0.0);
  EXPECT_EQ(by_rigid_fits.coarse.choice_disagreement, by_rigid_fits.coarse.disagreement);
  // Every rigid placement was compared, the chosen one scoring choice_disagreement.
  ASSERT_GE(by_rigid_fits.coarse.choices.size(), coarse.choices.size());
  const Eigen::Matrix3d& rigid_R = by_rigid_fits.coarse.placement.R;
  const auto rigid_chosen =
      std::find_if(by_rigid_fits.coarse.choices.begin(), by_rigid_fits.coarse.choices.end(),
                   [&](const PlacementChoice& p) { return p.R == rigid_R; });
  ASSERT_NE(rigid_chosen, by_rigid_fits.coarse.choices.end());
  EXPECT_EQ(rigid_chosen->disagreement, by_rigid_fits.coarse.choice_disagreement);
  EXPECT_EQ(by_rigid_fits.check.ambiguity,
            by_rigid_fits.coarse.choice_disagreement / by_rigid_fits.coarse.runner_up_disagreement);

  // Two placements alike at the choice, the chosen one fitted far better afterwards.
  CoarseResult alike = coarse;
  alike.choice_disagreement = 0.999 * alike.runner_up_disagreement;
  alike.disagreement = 0.5 * alike.runner_up_disagreement;
  const MorphCheck check = CheckMorph(*model_, alike, good.dense);
  EXPECT_NEAR(check.ambiguity, 0.999, 1e-12);
  EXPECT_LT(check.confidence, 0.3);
  EXPECT_NE(check.concern.find("placement ambiguous"), std::string::npos) << check.concern;
}

// MorphCarcass is AlignCoarse then MorphFromCoarse; the benchmark's --start-from-truth relies
// on the second going on from whatever coarse result it is handed.
TEST_F(MorphCheckTest, MorphFromCoarseGoesOnFromTheCoarseResultItIsGiven) {
  const Eigen::Matrix3Xd cloud = test::HangingCloud(*carcass_, 2000003u, 0.003);
  const MorphOptions options = Upright();
  const CarcassResult whole = MorphUpright(cloud);
  const CarcassResult split =
      MorphFromCoarse(*model_, carcass_->annotations, AlignCoarse(*model_, cloud, options.coarse),
                      cloud, {}, options);
  ASSERT_TRUE(whole.ok) << whole.error;
  ASSERT_TRUE(split.ok) << split.error;
  ASSERT_EQ(whole.cuts.size(), split.cuts.size());
  for (std::size_t c = 0; c < whole.cuts.size(); ++c) {
    EXPECT_LT((whole.cuts[c].plane.point - split.cuts[c].plane.point).norm(), 1e-6);
    EXPECT_GT(whole.cuts[c].plane.normal.dot(split.cuts[c].plane.normal), 1.0 - 1e-9);
  }

  CoarseResult failed;
  failed.error = "no skeleton";
  const CarcassResult refused =
      MorphFromCoarse(*model_, carcass_->annotations, failed, cloud, {}, options);
  EXPECT_FALSE(refused.ok);
  EXPECT_EQ(refused.error, "coarse stage: no skeleton");
  EXPECT_TRUE(refused.cuts.empty());
}

TEST_F(MorphCheckTest, UprightPriorOnlyConsidersPlacementsWithinTheTilt) {
  perception::PosedCarcass truth;
  const Eigen::Matrix3Xd cloud = test::HangingCloud(*carcass_, 2000005u, 0.003, &truth);
  for (const Eigen::Vector3d& up : {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0, 0, -1)}) {
    CoarseOptions options;
    options.upright = {.enabled = true, .target_up = up, .max_tilt_deg = 30};
    const CoarseResult r = AlignCoarse(*model_, cloud, options);
    if (!r.ok) {
      EXPECT_NE(r.error.find("within 30 degrees of upright"), std::string::npos) << r.error;
      continue;
    }
    const Eigen::Vector3d mapped = r.association.from_to.R * Eigen::Vector3d::UnitZ();
    EXPECT_GE(mapped.dot(up), std::cos(30.0 * 3.14159265358979 / 180.0) - 1e-9);
  }
}

}  // namespace
}  // namespace vb::morph
