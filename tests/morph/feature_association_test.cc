#include "morph/feature_association.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

namespace vb::morph {
namespace {

FeatureNodes RandomFeatures(int terminals, int junctions, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  FeatureNodes f;
  f.terminals.resize(3, terminals);
  f.junctions.resize(3, junctions);
  for (int i = 0; i < terminals; ++i)
    f.terminals.col(i) = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  for (int i = 0; i < junctions; ++i)
    f.junctions.col(i) = 0.3 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  return f;
}

// The target: the source moved by a similarity, shuffled, slightly perturbed.
FeatureNodes Transform(const FeatureNodes& f, const Similarity& s,
                       const std::vector<int>& terminal_order,
                       const std::vector<int>& junction_order, double noise, std::mt19937_64* rng) {
  std::normal_distribution<double> n(0.0, noise);
  FeatureNodes out;
  out.terminals.resize(3, static_cast<Eigen::Index>(terminal_order.size()));
  out.junctions.resize(3, static_cast<Eigen::Index>(junction_order.size()));
  for (std::size_t k = 0; k < terminal_order.size(); ++k) {
    out.terminals.col(static_cast<Eigen::Index>(k)) =
        s(f.terminals.col(terminal_order[k])) + Eigen::Vector3d(n(*rng), n(*rng), n(*rng));
  }
  for (std::size_t k = 0; k < junction_order.size(); ++k) {
    out.junctions.col(static_cast<Eigen::Index>(k)) =
        s(f.junctions.col(junction_order[k])) + Eigen::Vector3d(n(*rng), n(*rng), n(*rng));
  }
  return out;
}

class FeatureAssociationTest : public ::testing::TestWithParam<int> {};

TEST_P(FeatureAssociationTest, RecoversPairingAndSimilarity) {
  std::mt19937_64 rng(static_cast<std::uint64_t>(GetParam()));
  const FeatureNodes from = RandomFeatures(5, 2, &rng);
  const Similarity truth{1.3, Eigen::Quaterniond::UnitRandom().toRotationMatrix(),
                         Eigen::Vector3d(4, -2, 1)};
  const std::vector<int> order = {3, 0, 4, 1, 2};
  const FeatureNodes to = Transform(from, truth, order, {1, 0}, 0.002, &rng);
  const std::vector<Association> result = AssociateFeatureNodes(from, to);
  ASSERT_FALSE(result.empty());
  const Association& best = result.front();
  EXPECT_TRUE(best.ok);
  ASSERT_EQ(best.terminals.size(), 5u);
  for (const auto& [a, b] : best.terminals) EXPECT_EQ(order[static_cast<std::size_t>(b)], a);
  ASSERT_EQ(best.junctions.size(), 2u);
  for (const auto& [a, b] : best.junctions) EXPECT_EQ(1 - b, a);
  EXPECT_NEAR(best.from_to.scale, 1.3, 0.01);
  EXPECT_LT((best.from_to.R - truth.R).norm(), 0.02);
  EXPECT_LT(best.rms_residual, 0.01);
}

TEST_P(FeatureAssociationTest, LeavesOutASpuriousTargetTerminal) {
  std::mt19937_64 rng(static_cast<std::uint64_t>(GetParam()) + 100);
  const FeatureNodes from = RandomFeatures(5, 2, &rng);
  const Similarity truth{0.8, Eigen::Quaterniond::UnitRandom().toRotationMatrix(),
                         Eigen::Vector3d(0, 1, 0)};
  FeatureNodes to =
      Transform(from, truth, {2, 4, 0, 3}, {0, 1}, 0.002, &rng);  // terminal 1 is missing...
  to.terminals.conservativeResize(3, 5);
  to.terminals.col(4) = Eigen::Vector3d(9, 9, 9);  // ...and a spur stands far away
  const std::vector<Association> result = AssociateFeatureNodes(from, to);
  ASSERT_FALSE(result.empty());
  const Association& best = result.front();
  const std::vector<int> order = {2, 4, 0, 3};
  for (const auto& [a, b] : best.terminals) {
    ASSERT_LT(b, 4) << "paired the spur";
    EXPECT_EQ(order[static_cast<std::size_t>(b)], a);
  }
  EXPECT_EQ(best.terminals.size(), 4u);
}

INSTANTIATE_TEST_SUITE_P(Seeds, FeatureAssociationTest, ::testing::Range(1, 6));

TEST(FeatureAssociationEdgeTest, NeedsThreePairs) {
  std::mt19937_64 rng(3);
  const FeatureNodes from = RandomFeatures(2, 0, &rng);
  EXPECT_TRUE(AssociateFeatureNodes(from, from).empty());
  EXPECT_TRUE(AssociateFeatureNodes(FeatureNodes{}, RandomFeatures(5, 2, &rng)).empty());
}

TEST(FeatureAssociationEdgeTest, BoundsTheSearchOnLargeFeatureSets) {
  std::mt19937_64 rng(4);
  const FeatureNodes from = RandomFeatures(12, 6, &rng);
  const FeatureNodes to = RandomFeatures(12, 6, &rng);
  AssociationOptions options;
  options.max_candidates = 50'000;
  const std::vector<Association> result = AssociateFeatureNodes(from, to, options);
  ASSERT_FALSE(result.empty());
  EXPECT_LE(result.front().candidates, 50'000);
}

}  // namespace
}  // namespace vb::morph
