#include "morph/articulated_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "geometry/mesh_measures.h"
#include "morph/feature_association.h"
#include "perception/carcass_generator.h"
#include "tests/support/lamb_fixture.h"

namespace vb::morph {
namespace {

TEST(TrimmedDisagreementTest, IgnoresTheFarthestPairsOfEachSide) {
  std::srand(7);
  const Eigen::Matrix3Xd a = Eigen::Matrix3Xd::Random(3, 500);
  Eigen::Matrix3Xd b = a;
  b.leftCols(50).array() += 10.0;  // a tenth of b far away: a part a lacks
  const PointIndex a_index(a), b_index(b);
  EXPECT_LT(TrimmedDisagreement(a, a_index, b, b_index, 0.8), 1e-12);
  // Untrimmed, the far tenth counts: about 50 x 17 / 500 / 2 on the way back.
  EXPECT_GT(TrimmedDisagreement(a, a_index, b, b_index, 1.0), 0.5);
}

TEST(WeightedTrimmedDisagreementTest, WeighsEachSampleAndFallsBackToTheTrimmedMean) {
  std::srand(7);
  Eigen::Matrix3Xd a = Eigen::Matrix3Xd::Random(3, 500);
  const Eigen::Matrix3Xd b = a;
  a.leftCols(50).array() += 10.0;  // a tenth of a far away: a part b lacks
  const PointIndex a_index(a), b_index(b);
  // Alike weights (or none counting) give the trimmed mean, to the bit.
  const double plain = TrimmedDisagreement(a, a_index, b, b_index, 1.0);
  EXPECT_EQ(WeightedTrimmedDisagreement(a, a_index, std::vector<double>(500, 2.0), b, b_index, 1.0),
            plain);
  EXPECT_EQ(WeightedTrimmedDisagreement(a, a_index, std::vector<double>(500, 0.0), b, b_index, 1.0),
            plain);
  // The far tenth: about 50 x 17 / 500 / 2 on the way out.
  EXPECT_GT(plain, 0.6);
  EXPECT_LT(plain, 1.0);
  // The far tenth weighed at nothing counts nowhere: only b's points that lost their
  // partner, each paired with a near neighbour of weight 1, about 0.15 away: 0.0079.
  std::vector<double> weights(500, 1.0);
  std::fill_n(weights.begin(), 50, 0.0);
  const double weighted = WeightedTrimmedDisagreement(a, a_index, weights, b, b_index, 1.0);
  EXPECT_GT(weighted, 0.0055);
  EXPECT_LT(weighted, 0.011);
  // The target side takes its nearest template sample's weight, not its own column's.
  Eigen::Matrix3Xd c(3, 2), d(3, 2);
  c << 0, 10, 0, 0, 0, 0;  // (0, 0, 0), (10, 0, 0)
  d << 10, 1, 0, 0, 0, 0;  // (10, 0, 0), (1, 0, 0): its second lies 1 from c's first
  const PointIndex c_index(c), d_index(d);
  EXPECT_EQ(WeightedTrimmedDisagreement(c, c_index, {0.0, 1.0}, d, d_index, 1.0), 0.0);
  EXPECT_EQ(WeightedTrimmedDisagreement(c, c_index, {1.0, 1.0}, d, d_index, 1.0), 0.5);
}

TEST(HalfTurnAsymmetryTest, NearZeroWhereTheTurnMapsTheShapeOntoItself) {
  // A cylinder of radius 0.1 along z, 1 long, in pairs opposite each other across the axis,
  // and a nose: 10 points 0.3 out on one side, which the half turn puts where nothing is.
  Eigen::Matrix3Xd samples(3, 2010);
  for (int i = 0; i < 1000; ++i) {
    const double angle = 0.0731 * i, z = -0.5 + 0.001 * i;
    samples.col(2 * i) << 0.1 * std::cos(angle), 0.1 * std::sin(angle), z;
    samples.col(2 * i + 1) << -0.1 * std::cos(angle), -0.1 * std::sin(angle), z;
  }
  for (int i = 0; i < 10; ++i) samples.col(2000 + i) << 0.3, 0.0, -0.05 + 0.01 * i;
  samples.colwise() += Eigen::Vector3d(1.0, 2.0, 3.0);  // turned about its mean, not the origin
  const std::vector<double> asymmetry = HalfTurnAsymmetry(samples);
  ASSERT_EQ(asymmetry.size(), 2010u);
  // The nose moves the mean 0.0015 towards it, so the cylinder's points turn 0.003 off.
  for (int i = 0; i < 2000; ++i) EXPECT_LT(asymmetry[static_cast<std::size_t>(i)], 0.0035) << i;
  // The nose turns to -0.3, 0.2 from the cylinder's side nearest it.
  for (int i = 2000; i < 2010; ++i) {
    EXPECT_GT(asymmetry[static_cast<std::size_t>(i)], 0.19) << i;
    EXPECT_LT(asymmetry[static_cast<std::size_t>(i)], 0.21) << i;
  }
}

TEST(MutualNearestPairsTest, PairsOnlyMutualNeighboursWithinTheRadius) {
  Eigen::Matrix3Xd a(3, 2), b(3, 3);
  a << 0, 1, 0, 0, 0, 0;
  b << 0.05, 0.9, 5, 0, 0, 5, 0, 0, 5;
  using Pairs = std::vector<std::pair<int, int>>;
  EXPECT_EQ(MutualNearestPairs(a, b, 0.2), (Pairs{{0, 0}, {1, 1}}));
  EXPECT_EQ(MutualNearestPairs(a, b, 0.07), (Pairs{{0, 0}}));
  EXPECT_TRUE(MutualNearestPairs(a, Eigen::Matrix3Xd(3, 0), 1.0).empty());
}

class ArticulateTemplateTest : public test::LambTemplateTest {
 protected:
  // A posed lamb brought into the template's normalised frame by the similarity that best
  // lays the template's vertices on it (what a perfect rigid placement would do).
  struct Case {
    Eigen::Matrix3Xd truth;  // vertex i of the template, posed, normalised frame
    double rigid_error = 0.0;  // mean vertex error of the template unposed, template sizes
  };
  Case Posed(std::uint64_t seed) const {
    const perception::PosedCarcass posed =
        perception::PoseCarcass(*carcass_, perception::SampleCarcassPose(seed));
    const Similarity to_template =
        Similarity::FromUmeyama(Eigen::umeyama(posed.mesh.V, model_->V, true));
    Case c;
    c.truth.resize(3, posed.mesh.V.cols());
    for (Eigen::Index i = 0; i < c.truth.cols(); ++i) c.truth.col(i) = to_template(posed.mesh.V.col(i));
    c.rigid_error = (model_->V - c.truth).colwise().norm().mean();
    return c;
  }
  double Error(const DeformationState& state, const Eigen::Matrix3Xd& truth,
               const std::vector<int>& only = {}) const {
    const Eigen::Matrix3Xd posed = DeformPoints(model_->graph, model_->vertex_weights, model_->V, state);
    if (only.empty()) return (posed - truth).colwise().norm().mean();
    double sum = 0.0;
    for (int i : only) sum += (posed.col(i) - truth.col(i)).norm();
    return sum / static_cast<double>(only.size());
  }
};

TEST_F(ArticulateTemplateTest, TurnsTheLimbsIntoTheTargetsPose) {
  for (std::uint64_t seed : {1000003u, 1000004u, 1000008u}) {
    const Case c = Posed(seed);
    const PointIndex index(c.truth);
    const ArticulationResult r = ArticulateTemplate(
        *model_, c.truth, index, Eigen::Matrix3Xd(3, 0),
        DeformationState::Identity(model_->graph.num_nodes()), ArticulationOptions{}, Similarity{});
    ASSERT_TRUE(r.ok);
    EXPECT_EQ(r.rounds, ArticulationOptions{}.rounds);
    const double error = Error(r.state, c.truth);
    // Measured: 0.41, 0.30 and 0.43 of the rigid error.
    EXPECT_LT(error, 0.5 * c.rigid_error) << "seed " << seed << ", rigid " << c.rigid_error;
  }
}

TEST_F(ArticulateTemplateTest, FitsATargetLeftInItsOwnFrameAsOneBroughtIntoTheTemplates) {
  // The same target, with limb ends pulling, handed over in the template's frame, or in a
  // frame 2.5 times larger, turned and moved, with the similarity between them: the same fit,
  // up to rounding.
  const Case c = Posed(1000003u);
  const Similarity placement{
      2.5, Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(),
      Eigen::Vector3d(0.4, -3.0, 1.5)};
  const auto move = [&](const Eigen::Matrix3Xd& points) {
    Eigen::Matrix3Xd out(3, points.cols());
    for (Eigen::Index i = 0; i < points.cols(); ++i) out.col(i) = placement(points.col(i));
    return out;
  };
  const Eigen::Matrix3Xd there = move(c.truth);
  // Limb ends: the template's own, a stand-in for the target's skeleton.
  const Eigen::Matrix3Xd& tips = model_->features.terminals;
  const PointIndex here_index(c.truth), there_index(there);
  ArticulationOptions options;
  options.rounds = 2;
  options.terminal_weight = 5.0;
  const DeformationState identity = DeformationState::Identity(model_->graph.num_nodes());
  const ArticulationResult here =
      ArticulateTemplate(*model_, c.truth, here_index, tips, identity, options, Similarity{});
  const ArticulationResult moved =
      ArticulateTemplate(*model_, there, there_index, move(tips), identity, options, placement);
  ASSERT_TRUE(here.ok && moved.ok);
  EXPECT_NEAR(moved.disagreement, here.disagreement, 1e-9);
  // It fitted: measured 0.55 of the rigid error.
  EXPECT_LT(Error(moved.state, c.truth), 0.7 * c.rigid_error);
  EXPECT_NEAR(Error(moved.state, c.truth), Error(here.state, c.truth), 1e-6);
  // The limb ends were carried too: without them the fit differs (measured by 2.8e-4 template
  // sizes of mean vertex error).
  options.terminal_weight = 0.0;
  const ArticulationResult untipped =
      ArticulateTemplate(*model_, there, there_index, move(tips), identity, options, placement);
  EXPECT_GT(std::abs(Error(untipped.state, c.truth) - Error(moved.state, c.truth)), 1.5e-4);
}

TEST_F(ArticulateTemplateTest, NormalsKeepAFinBesideTheSurfaceFromPullingIt) {
  // A posed lamb with a fin of points standing out of one flank, square to it, as an arm
  // hanging beside a body stands to its flank: near the fin's root the two are close but
  // face apart. The target is handed over in a frame of its own (turned, moved, 2.5 times
  // larger), its normals with every other one reversed (a cloud's have no sign).
  const Case c = Posed(1000003u);
  geometry::TriangleMesh posed{c.truth, model_->mesh.F, {}};
  posed.N = geometry::VertexNormals(posed);
  Eigen::Index root = 0;
  c.truth.row(1).maxCoeff(&root);
  const Eigen::Vector3d out = posed.N.col(root);
  const Eigen::Vector3d along = out.unitOrthogonal();
  const int rows = 40, columns = 40;
  Eigen::Matrix3Xd here(3, c.truth.cols() + rows * columns);
  Eigen::Matrix3Xd here_normals(3, here.cols());
  here.leftCols(c.truth.cols()) = c.truth;
  here_normals.leftCols(c.truth.cols()) = posed.N;
  for (int a = 0; a < rows; ++a) {
    for (int b = 0; b < columns; ++b) {
      const Eigen::Index k = c.truth.cols() + a * columns + b;
      here.col(k) = c.truth.col(root) + (0.01 + 0.15 * a / rows) * out +
                    0.15 * (b / static_cast<double>(columns) - 0.5) * along;
      here_normals.col(k) = out.cross(along);
    }
  }
  const Similarity placement{
      2.5, Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(),
      Eigen::Vector3d(0.4, -3.0, 1.5)};
  Eigen::Matrix3Xd target(3, here.cols()), normals(3, here.cols());
  for (Eigen::Index i = 0; i < here.cols(); ++i) {
    target.col(i) = placement(here.col(i));
    normals.col(i) = (i % 2 == 0 ? 1.0 : -1.0) * (placement.R * here_normals.col(i));
  }
  std::vector<int> near;
  for (Eigen::Index i = 0; i < c.truth.cols(); ++i)
    if ((c.truth.col(i) - c.truth.col(root)).norm() < 0.15) near.push_back(static_cast<int>(i));
  const PointIndex index(target);
  const DeformationState identity = DeformationState::Identity(model_->graph.num_nodes());
  const Eigen::Matrix3Xd none(3, 0);
  const ArticulationResult plain =
      ArticulateTemplate(*model_, target, index, none, identity, ArticulationOptions{}, placement);
  const ArticulationResult facing = ArticulateTemplate(
      *model_, target, index, none, identity, ArticulationOptions{}, placement, nullptr, &normals);
  ASSERT_TRUE(plain.ok && facing.ok);
  // The same fit as on the target in the template's frame with its normals all outward: the
  // frames and the signs do not matter.
  const PointIndex here_index(here);
  const ArticulationResult facing_here =
      ArticulateTemplate(*model_, here, here_index, none, identity, ArticulationOptions{},
                         Similarity{}, nullptr, &here_normals);
  ASSERT_TRUE(facing_here.ok);
  EXPECT_NEAR(Error(facing.state, c.truth), Error(facing_here.state, c.truth), 1e-6);
  // Measured near the root (within 0.15 template sizes): by nearness alone the fin drags the
  // flank out to 3.2 times its rigid error (0.0386 against 0.0120); facing alike, 0.68 of it
  // (0.0081), and over the whole template 0.0088 against 0.0136.
  const double rigid_near = Error(identity, c.truth, near);
  const double plain_near = Error(plain.state, c.truth, near);
  EXPECT_GT(plain_near, 2.5 * rigid_near);
  EXPECT_LT(Error(facing.state, c.truth, near), 0.8 * rigid_near);
  EXPECT_LT(Error(facing.state, c.truth), 0.8 * Error(plain.state, c.truth));
}

TEST_F(ArticulateTemplateTest, APartTheTargetLacksFollowsItsNeighbours) {
  // A camera shadow: the target loses everything beyond 75 % of its extent along x.
  const Case c = Posed(1000004u);
  const Eigen::RowVectorXd x = c.truth.row(0);
  const double cut = x.minCoeff() + 0.75 * (x.maxCoeff() - x.minCoeff());
  std::vector<int> hidden, shown;
  for (Eigen::Index i = 0; i < x.size(); ++i) (x(i) > cut ? hidden : shown).push_back(static_cast<int>(i));
  Eigen::Matrix3Xd partial(3, static_cast<Eigen::Index>(shown.size()));
  for (std::size_t k = 0; k < shown.size(); ++k) partial.col(static_cast<Eigen::Index>(k)) = c.truth.col(shown[k]);
  const PointIndex index(partial);
  const DeformationState identity = DeformationState::Identity(model_->graph.num_nodes());
  const ArticulationResult r = ArticulateTemplate(*model_, partial, index, Eigen::Matrix3Xd(3, 0),
                                                  identity, ArticulationOptions{}, Similarity{});
  ASSERT_TRUE(r.ok);
  const double rigid_hidden = Error(identity, c.truth, hidden);
  const double hidden_error = Error(r.state, c.truth, hidden);
  // Not pulled into the hole: no worse than where the rigid placement left it (measured
  // 0.80 of it); the shown part 0.57 of its rigid error.
  EXPECT_LT(hidden_error, rigid_hidden);
  EXPECT_LT(Error(r.state, c.truth, shown), 0.75 * Error(identity, c.truth, shown));
}

}  // namespace
}  // namespace vb::morph
