#include "morph/skeleton_graph.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "morph/skeleton_branches.h"

namespace vb::morph {
namespace {

// Adds a straight chain of `n` edges from node `from` to point `to`; returns the last node.
int Chain(SkeletonGraph* g, int from, const Eigen::Vector3d& to, int n) {
  const Eigen::Vector3d start = g->nodes.col(from);
  int previous = from;
  for (int k = 1; k <= n; ++k) {
    g->nodes.conservativeResize(3, g->num_nodes() + 1);
    g->nodes.col(g->num_nodes() - 1) = start + (to - start) * k / n;
    g->edges.push_back({previous, g->num_nodes() - 1});
    previous = g->num_nodes() - 1;
  }
  return previous;
}

SkeletonGraph Star() {
  SkeletonGraph g;
  g.nodes = Eigen::Vector3d::Zero();
  Chain(&g, 0, {1, 0, 0}, 10);
  Chain(&g, 0, {-1, 0, 0}, 10);
  Chain(&g, 0, {0, 1, 0}, 10);
  return g;
}

TEST(SkeletonGraphTest, StarHasThreeTerminalsAndOneJunction) {
  const FeatureNodes f = ExtractFeatureNodes(Star(), {});
  EXPECT_EQ(f.num_terminals(), 3);
  ASSERT_EQ(f.num_junctions(), 1);
  EXPECT_LT(f.junctions.col(0).norm(), 1e-12);
}

TEST(SkeletonGraphTest, PrunesShortSpursRepeatedly) {
  SkeletonGraph g = Star();
  // A spur of length 0.03 on arm 1, and a spur with a spur of its own.
  Chain(&g, 5, {0.5, 0.03, 0}, 2);
  const int fork = Chain(&g, 15, {-0.5, -0.02, 0}, 1);
  Chain(&g, fork, {-0.5, -0.04, 0.01}, 1);
  Chain(&g, fork, {-0.5, -0.04, -0.01}, 1);
  const FeatureNodes f =
      ExtractFeatureNodes(g, {.min_branch_length = 0.05, .junction_merge_distance = 0.05});
  EXPECT_EQ(f.num_terminals(), 3);
  EXPECT_EQ(f.num_junctions(), 1);
}

TEST(SkeletonGraphTest, MergesNearbyJunctionsIntoTheirMean) {
  SkeletonGraph g;
  g.nodes = Eigen::Vector3d::Zero();
  const int second = Chain(&g, 0, {0.04, 0, 0}, 2);
  Chain(&g, 0, {-1, 0, 0}, 10);
  Chain(&g, 0, {0, 1, 0}, 10);
  Chain(&g, second, {1, 0, 0}, 10);
  Chain(&g, second, {0, -1, 0}, 10);
  const FeatureNodes merged =
      ExtractFeatureNodes(g, {.min_branch_length = 0.05, .junction_merge_distance = 0.05});
  EXPECT_EQ(merged.num_terminals(), 4);
  ASSERT_EQ(merged.num_junctions(), 1);
  EXPECT_NEAR(merged.junctions(0, 0), 0.02, 1e-12);
  const FeatureNodes separate =
      ExtractFeatureNodes(g, {.min_branch_length = 0.05, .junction_merge_distance = 0.01});
  EXPECT_EQ(separate.num_junctions(), 2);
}

TEST(SkeletonGraphTest, AChainIsItsTwoEnds) {
  SkeletonGraph g;
  g.nodes = Eigen::Vector3d::Zero();
  Chain(&g, 0, {0.02, 0, 0}, 3);  // shorter than the spur length: still kept, it is all there is
  const FeatureNodes f =
      ExtractFeatureNodes(g, {.min_branch_length = 0.05, .junction_merge_distance = 0.05});
  EXPECT_EQ(f.num_terminals(), 2);
  EXPECT_EQ(f.num_junctions(), 0);
}

// Each limb runs from the feature junction to its terminal along the skeleton, past the
// junctions of pruned spurs, root first.
TEST(SkeletonBranchesTest, RunFromTheJunctionToEachTerminalPastSpurs) {
  SkeletonGraph g = Star();
  Chain(&g, 5, {0.5, 0.03, 0}, 2);  // a spur on the +x arm, pruned below
  const FeatureNodes f =
      ExtractFeatureNodes(g, {.min_branch_length = 0.05, .junction_merge_distance = 0.05});
  ASSERT_EQ(f.num_terminals(), 3);
  const std::vector<SkeletonBranch> branches = TerminalBranches(g, f);
  ASSERT_EQ(branches.size(), 3u);
  for (const SkeletonBranch& b : branches) {
    ASSERT_EQ(b.nodes.size(), b.distance.size());
    EXPECT_EQ(b.nodes.front(), 0) << "the root is the junction";
    EXPECT_TRUE(g.nodes.col(b.nodes.back()).isApprox(f.terminals.col(b.terminal)));
    EXPECT_NEAR(b.length(), 1.0, 1e-12);
    EXPECT_TRUE(std::is_sorted(b.distance.begin(), b.distance.end()));
    // Halfway out along the arm, between its 5th and 6th nodes' nearest.
    int node = -1;
    const Eigen::Vector3d half = PointAlong(g, b, 0.5, &node);
    EXPECT_NEAR(half.norm(), 0.5, 1e-12);
    EXPECT_NEAR((half - 0.5 * f.terminals.col(b.terminal)).norm(), 0.0, 1e-12);
    EXPECT_NEAR((g.nodes.col(node) - half).norm(), 0.0, 1e-12);
    EXPECT_NEAR((PointAlong(g, b, 0.33) - 0.33 * f.terminals.col(b.terminal)).norm(), 0.0, 1e-12);
    EXPECT_TRUE(PointAlong(g, b, 1.0).isApprox(f.terminals.col(b.terminal)));
    EXPECT_NEAR(PointAlong(g, b, 0.0).norm(), 0.0, 1e-12);
  }
}

TEST(SkeletonBranchesTest, AChainWithoutJunctionsHasNone) {
  SkeletonGraph g;
  g.nodes = Eigen::Vector3d::Zero();
  Chain(&g, 0, {1, 0, 0}, 10);
  const FeatureNodes f = ExtractFeatureNodes(g, {});
  EXPECT_EQ(f.num_junctions(), 0);
  EXPECT_TRUE(TerminalBranches(g, f).empty());
}

}  // namespace
}  // namespace vb::morph
