#include "morph/embedded_deformation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <span>
#include <vector>

#include "tests/support/test_meshes.h"

namespace vb::morph {
namespace {

class EmbeddedDeformationTest : public ::testing::Test {
 protected:
  EmbeddedDeformationTest() : mesh_(test::Sphere(1.0, 4)) {
    graph_ = BuildDeformationGraph(mesh_, options_);
    weights_ = VertexWeights(mesh_, graph_, options_);
  }
  PointConstraint Constraint(int vertex, const Eigen::Vector3d& target) const {
    PointConstraint c;
    c.rest = mesh_.V.col(vertex);
    c.target = target;
    for (Eigen::Index k = 0; k < weights_.nodes.rows(); ++k) {
      c.nodes.push_back(weights_.nodes(k, vertex));
      c.weights.push_back(weights_.weights(k, vertex));
    }
    return c;
  }
  geometry::TriangleMesh mesh_;
  DeformationGraphOptions options_;
  DeformationGraph graph_;
  NodeWeights weights_;
};

TEST_F(EmbeddedDeformationTest, WithoutDataNothingMoves) {
  DeformationState state = DeformationState::Identity(graph_.num_nodes());
  const SolveSummary summary = SolveEmbeddedDeformation(graph_, {}, {}, &state);
  EXPECT_TRUE(summary.usable);
  EXPECT_LT((DeformPoints(graph_, weights_, mesh_.V, state) - mesh_.V).cwiseAbs().maxCoeff(), 1e-9);
}

// A chain of five nodes (every edge a bridge, so E_rig acts; named both ways round) with
// point and plane terms on random nodes, at a random state away from the identity.
struct ChainProblem {
  ChainProblem() : state(DeformationState::Identity(5)) {
    std::mt19937 rng(7);
    std::normal_distribution<double> noise(0.0, 1.0);
    graph.nodes.resize(3, 5);
    for (int j = 0; j < 5; ++j) graph.nodes.col(j) = Eigen::Vector3d(0.3 * j, 0.05 * j * j, 0.0);
    graph.neighbours.resize(5);
    for (int j = 0; j < 5; ++j) {
      if (j > 0) graph.neighbours[static_cast<std::size_t>(j)].push_back(j - 1);
      if (j < 4) graph.neighbours[static_cast<std::size_t>(j)].push_back(j + 1);
      if (j < 4) graph.edges.push_back({j, j + 1});
    }
    for (const auto& [j, k] : graph.edges)
      graph.bridges.push_back(j % 2 == 0 ? std::array<int, 2>{j, k} : std::array<int, 2>{k, j});
    for (int c = 0; c < 12; ++c) {
      PointConstraint p;
      const int a = c % 5, b = (c + 2) % 5;
      p.nodes = {a, b};
      p.weights = {0.7, 0.3};
      p.rest = 0.7 * graph.nodes.col(a) + 0.3 * graph.nodes.col(b) +
               0.1 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      p.target = p.rest + 0.2 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      if (c % 2 == 1) p.normal = Eigen::Vector3d(noise(rng), noise(rng), noise(rng)).normalized();
      p.weight = 0.5 + 0.1 * c;
      constraints.push_back(p);
    }
    for (int j = 0; j < 5; ++j) {
      Eigen::Matrix3d A = state.rotation(j);
      for (int e = 0; e < 9; ++e) A(e / 3, e % 3) += 0.2 * noise(rng);
      state.set_rotation(j, A);
      state.t[static_cast<std::size_t>(j)] =
          0.1 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    }
  }
  DeformationGraph graph;
  std::vector<PointConstraint> constraints;
  DeformationState state;
  EmbeddedDeformationOptions options = [] {
    EmbeddedDeformationOptions o;
    o.w_data = 3.0;
    o.w_rot = 2.0;
    o.w_reg = 5.0;
    o.w_rig = 7.0;
    return o;
  }();
};

// The energy's gradient at @p p's state against central differences, with @p kept_bends.
void ExpectGradientMatchesFiniteDifferences(const ChainProblem& p,
                                            std::span<const Eigen::Vector3d> kept_bends) {
  Eigen::VectorXd gradient;
  const double energy =
      EmbeddedDeformationEnergy(p.graph, p.constraints, p.options, p.state, &gradient, kept_bends);
  ASSERT_GT(energy, 0.0);
  ASSERT_EQ(gradient.size(), 12 * 5);
  const double h = 1e-6;
  for (int j = 0; j < 5; ++j) {
    for (int e = 0; e < 12; ++e) {
      DeformationState plus = p.state, minus = p.state;
      const auto nudge = [&](DeformationState* s, double by) {
        if (e < 9)
          s->R[static_cast<std::size_t>(j)][e] += by;
        else
          s->t[static_cast<std::size_t>(j)][e - 9] += by;
      };
      nudge(&plus, h);
      nudge(&minus, -h);
      const double numeric =
          (EmbeddedDeformationEnergy(p.graph, p.constraints, p.options, plus, nullptr, kept_bends) -
           EmbeddedDeformationEnergy(p.graph, p.constraints, p.options, minus, nullptr,
                                     kept_bends)) /
          (2 * h);
      EXPECT_NEAR(gradient[12 * j + e], numeric, 1e-6 * (1.0 + std::abs(numeric)))
          << "node " << j << " entry " << e;
    }
  }
}

TEST(EmbeddedDeformationEnergyTest, GradientMatchesFiniteDifferences) {
  ExpectGradientMatchesFiniteDifferences(ChainProblem{}, {});
}

TEST(EmbeddedDeformationEnergyTest, GradientMatchesFiniteDifferencesWithKeptBends) {
  // The bends of a pose other than the state's, some kept in part and some not at all.
  ChainProblem p;
  DeformationState pose = DeformationState::Identity(5);
  pose.set_rotation(3, Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  pose.t[4] = Eigen::Vector3d(0.01, -0.2, 0.05);
  const std::vector<Eigen::Vector3d> kept = KeptBends(p.graph, pose, 0.2);
  ASSERT_TRUE(std::any_of(kept.begin(), kept.end(), [](const auto& b) { return b.isZero(); }));
  ASSERT_TRUE(std::any_of(kept.begin(), kept.end(), [](const auto& b) { return !b.isZero(); }));
  ExpectGradientMatchesFiniteDifferences(p, kept);
}

// A chain's last two nodes turned 60 degrees about the middle node, rigidly: the bend a
// posture fit makes at a joint. E_rig is left out (every edge of the chain is a bridge).
struct BentChain {
  BentChain() {
    options.w_rig = 0.0;
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(std::numbers::pi / 3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d joint = chain.graph.nodes.col(2);
    for (int j = 3; j < 5; ++j) {
      const Eigen::Vector3d g = chain.graph.nodes.col(j);
      pose.set_rotation(j, turn);
      pose.t[static_cast<std::size_t>(j)] = turn * (g - joint) + joint - g;
    }
  }
  // Where the solve without data terms, from the pose, leaves the last node: its distance
  // from where the pose put it.
  double Drift(std::span<const Eigen::Vector3d> kept_bends) const {
    DeformationState state = pose;
    const SolveSummary summary =
        SolveEmbeddedDeformation(chain.graph, {}, options, &state, kept_bends);
    EXPECT_TRUE(summary.usable) << summary.message;
    return (state.t[4] - pose.t[4]).norm();
  }
  ChainProblem chain;
  DeformationState pose = DeformationState::Identity(5);
  EmbeddedDeformationOptions options;
};

TEST(KeptBendsTest, ShortensEachResidualByTheFreeBendTimesItsEdge) {
  const BentChain bent;
  const DeformationGraph& graph = bent.chain.graph;
  for (double free_bend : {0.0, 0.2, 10.0}) {
    const std::vector<Eigen::Vector3d> kept = KeptBends(graph, bent.pose, free_bend);
    std::size_t edge = 0;
    for (int i = 0; i < 5; ++i) {
      for (int j : graph.neighbours[static_cast<std::size_t>(i)]) {
        const Eigen::Vector3d d = graph.nodes.col(i) - graph.nodes.col(j);
        const Eigen::Vector3d bend = bent.pose.rotation(j) * d + graph.nodes.col(j) +
                                     bent.pose.t[static_cast<std::size_t>(j)] - graph.nodes.col(i) -
                                     bent.pose.t[static_cast<std::size_t>(i)];
        const double length = std::max(0.0, bend.norm() - free_bend * d.norm());
        ASSERT_LT(edge, kept.size());
        EXPECT_NEAR(kept[edge].norm(), length, 1e-12) << "edge " << i << "-" << j;
        if (length > 0) {
          EXPECT_NEAR(kept[edge].dot(bend), length * bend.norm(), 1e-12);
        }
        ++edge;
      }
    }
    EXPECT_EQ(edge, kept.size());
  }
  // The turn is about node 2, so node 2 is where node 3 carries it: of all the residuals only
  // node 3 as node 2 carries it is bent.
  const std::vector<Eigen::Vector3d> kept = KeptBends(graph, bent.pose, 0.0);
  EXPECT_EQ(std::count_if(kept.begin(), kept.end(), [](const auto& b) { return b.norm() > 1e-12; }),
            1);
}

TEST(KeptBendsTest, ASolveKeepsABendSharperThanTheFreeBendAndRelaxesTheRest) {
  // Without kept bends, E_reg pulls the turned part back towards the straight chain; with all
  // of the pose's bends kept (free bend 0) the pose is already the minimum; with a free bend
  // of 0.2 (about 11 degrees) the joint gives back a little of its turn; a free bend past
  // every bend keeps none. Measured drift of the last node, which the turn moved 0.85: 0.334
  // relaxed, 0 all kept, 0.0738 with the free bend. Bounds 1.5x.
  const BentChain bent;
  const double relaxed = bent.Drift({});
  EXPECT_GT(relaxed, 0.334 / 1.5);
  EXPECT_LT(bent.Drift(KeptBends(bent.chain.graph, bent.pose, 0.0)), 1e-12);
  const double some_kept = bent.Drift(KeptBends(bent.chain.graph, bent.pose, 0.2));
  EXPECT_GT(some_kept, 0.0738 / 1.5);
  EXPECT_LT(some_kept, 0.0738 * 1.5);
  EXPECT_EQ(bent.Drift(KeptBends(bent.chain.graph, bent.pose, 100.0)), relaxed);
}

// Measured: 24 (a first-order step, or J^T J without E_rig's blocks, needs far more).
constexpr int kChainIterations = 36;
constexpr int kQuadraticIterations = 7;  // measured: 5

TEST(EmbeddedDeformationEnergyTest, IsHalfTheWeightedSumOfTheSquaredTerms) {
  // Node 0 stretched twice along x, every other node at the identity; one point term on node
  // 0 alone, 0.1 off along x, and one plane term whose plane holds the deformed point.
  ChainProblem p;
  p.state = DeformationState::Identity(5);
  p.state.set_rotation(0, Eigen::Vector3d(2, 1, 1).asDiagonal());
  const Eigen::Vector3d g0 = p.graph.nodes.col(0);
  PointConstraint point;
  point.nodes = {0};
  point.weights = {1.0};
  point.rest = g0 + Eigen::Vector3d(0.1, 0, 0);  // carried to g0 + (0.2, 0, 0)
  point.target = point.rest;
  point.weight = 2.0;
  PointConstraint plane = point;
  plane.normal = Eigen::Vector3d::UnitY();
  const std::vector<PointConstraint> constraints = {point, plane};
  // E_rot: R_0^T R_0 - I = diag(3, 0, 0). E_rig, bridge (0, 1): R_0^T R_1 - I = diag(1, 0, 0).
  // E_reg, node 1 predicted by node 0: (R_0 - I)(g_1 - g_0) = (0.3, 0, 0). Data: w_data
  // times the term's weight times 0.1^2; the plane term is zero.
  const double expected = 0.5 * (2.0 * 9.0 + 7.0 * 1.0 + 5.0 * 0.3 * 0.3 + 3.0 * 2.0 * 0.1 * 0.1);
  EXPECT_NEAR(EmbeddedDeformationEnergy(p.graph, constraints, p.options, p.state), expected, 1e-12);
}

// Solves @p p with near-exact steps and no early stop; @p gradient_drop: the gradient's
// largest entry after the solve over before.
SolveSummary SolveExactly(ChainProblem* p, double linear_tolerance, double* gradient_drop) {
  p->options.linear_tolerance = linear_tolerance;
  p->options.function_tolerance = 1e-15;
  p->options.max_iterations = 100;
  Eigen::VectorXd before, after;
  EmbeddedDeformationEnergy(p->graph, p->constraints, p->options, p->state, &before);
  const SolveSummary summary =
      SolveEmbeddedDeformation(p->graph, p->constraints, p->options, &p->state);
  EmbeddedDeformationEnergy(p->graph, p->constraints, p->options, p->state, &after);
  *gradient_drop = after.lpNorm<Eigen::Infinity>() / before.lpNorm<Eigen::Infinity>();
  return summary;
}

TEST(EmbeddedDeformationSolveTest, ReachesAStationaryPoint) {
  // Every term at once, the nonlinear ones (E_rot, E_rig) included: with exact steps
  // Levenberg-Marquardt on the Gauss-Newton matrix ends where the gradient vanishes.
  ChainProblem p;
  double gradient_drop = 0.0;
  const SolveSummary summary = SolveExactly(&p, 1e-10, &gradient_drop);
  ASSERT_TRUE(summary.usable) << summary.message;
  EXPECT_DOUBLE_EQ(EmbeddedDeformationEnergy(p.graph, p.constraints, p.options, p.state),
                   summary.final_cost);
  EXPECT_LT(summary.final_cost, summary.initial_cost);
  EXPECT_LT(gradient_drop, 1e-9) << summary.message << " after " << summary.iterations
                                 << " iterations";
  EXPECT_LE(summary.iterations, kChainIterations);
}

TEST(EmbeddedDeformationSolveTest, SolvesAQuadraticInAFewSteps) {
  // Without E_rot and E_rig the energy is quadratic: with exact steps only the damping, a
  // ten-thousandth of J^T J's diagonal and falling, keeps the first steps from the minimum. A
  // wrong block of the linear terms' J^T J would make every step miss it.
  ChainProblem p;
  p.options.w_rot = 0.0;
  p.options.w_rig = 0.0;
  double gradient_drop = 0.0;
  const SolveSummary summary = SolveExactly(&p, 1e-12, &gradient_drop);
  ASSERT_TRUE(summary.usable) << summary.message;
  EXPECT_LT(gradient_drop, 1e-9);
  EXPECT_LE(summary.iterations, kQuadraticIterations);
}

TEST(EmbeddedDeformationSolveTest, PastTheDeadlineLeavesTheStateAsGiven) {
  ChainProblem p;
  const std::atomic<bool> cancel{true};
  p.options.deadline.cancel = &cancel;
  const DeformationState given = p.state;
  const SolveSummary summary =
      SolveEmbeddedDeformation(p.graph, p.constraints, p.options, &p.state);
  EXPECT_FALSE(summary.usable);
  EXPECT_EQ(summary.message, "past the morph's deadline");
  for (std::size_t j = 0; j < given.R.size(); ++j) {
    EXPECT_EQ(p.state.R[j], given.R[j]);
    EXPECT_EQ(p.state.t[j], given.t[j]);
  }
}

TEST(DeformNormalsTest, TurnsNormalsByTheInverseTransposeOfEachNode) {
  // Two nodes; point 0 moved by node 0 alone, point 1 by both, point 2 by none.
  NodeWeights weights;
  weights.nodes.resize(2, 3);
  weights.weights.resize(2, 3);
  weights.nodes << 0, 0, -1, -1, 1, -1;
  weights.weights << 1.0, 0.5, 0.0, 0.0, 0.5, 0.0;
  DeformationState state = DeformationState::Identity(2);
  const Eigen::Vector3d n = Eigen::Vector3d(1, 1, 0).normalized();
  Eigen::Matrix3Xd normals(3, 3);
  normals << n, n, n;
  // Identity: unchanged, except where no node acts (zero).
  Eigen::Matrix3Xd turned = DeformNormals(weights, normals, state);
  EXPECT_LT((turned.leftCols(2) - normals.leftCols(2)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(turned.col(2), Eigen::Vector3d::Zero());
  // Node 0 stretches x twice: a surface x = y then runs along (2, 1, 0) and its normal is
  // A^-T n ~ (1, 2, 0), not A n ~ (2, 1, 0). Node 1 turns 90 degrees about z.
  const Eigen::Matrix3d stretch = Eigen::Vector3d(2, 1, 1).asDiagonal();
  state.set_rotation(0, stretch);
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  state.set_rotation(1, turn);
  turned = DeformNormals(weights, normals, state);
  const Eigen::Vector3d stretched = Eigen::Vector3d(1, 2, 0).normalized();
  EXPECT_LT((turned.col(0) - stretched).norm(), 1e-12);
  // Point 1: the weighted blend of the two nodes' cofactor images (det 2 and 1), made unit.
  const Eigen::Vector3d blend =
      (0.5 * 2.0 * Eigen::Vector3d(0.5, 1, 0) / std::sqrt(2.0) + 0.5 * (turn * n)).normalized();
  EXPECT_LT((turned.col(1) - blend).norm(), 1e-12);
}

TEST_F(EmbeddedDeformationTest, RecoversARigidMotion) {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.3, -0.2, 0.5);
  std::vector<PointConstraint> constraints;
  for (int v = 0; v < mesh_.num_vertices(); v += 25)
    constraints.push_back(Constraint(v, R * mesh_.V.col(v) + t));
  DeformationState state = DeformationState::Identity(graph_.num_nodes());
  const SolveSummary summary = SolveEmbeddedDeformation(graph_, constraints, {}, &state);
  ASSERT_TRUE(summary.usable) << summary.message;
  const Eigen::Matrix3Xd moved = DeformPoints(graph_, weights_, mesh_.V, state);
  const Eigen::Matrix3Xd expected = (R * mesh_.V).colwise() + t;
  EXPECT_LT((moved - expected).colwise().norm().maxCoeff(), 0.01);
}

TEST_F(EmbeddedDeformationTest, PullingOnePointMovesItsNeighbourhoodNotTheFarSide) {
  Eigen::Index top = 0, bottom = 0;
  mesh_.V.row(2).maxCoeff(&top);
  mesh_.V.row(2).minCoeff(&bottom);
  const std::vector<PointConstraint> constraints = {
      Constraint(static_cast<int>(top), mesh_.V.col(top) + Eigen::Vector3d(0, 0, 0.3)),
      Constraint(static_cast<int>(bottom), mesh_.V.col(bottom))};
  DeformationState state = DeformationState::Identity(graph_.num_nodes());
  ASSERT_TRUE(SolveEmbeddedDeformation(graph_, constraints, {}, &state).usable);
  const Eigen::Matrix3Xd moved = DeformPoints(graph_, weights_, mesh_.V, state);
  EXPECT_NEAR(moved(2, top) - mesh_.V(2, top), 0.3, 0.03);
  EXPECT_LT((moved.col(bottom) - mesh_.V.col(bottom)).norm(), 0.03);
}

TEST_F(EmbeddedDeformationTest, PointToPlaneOnlyActsAlongTheNormal) {
  // Eq. (14): a target 0.2 away sideways but on the point's tangent plane changes nothing.
  Eigen::Index top = 0;
  mesh_.V.row(2).maxCoeff(&top);
  PointConstraint c =
      Constraint(static_cast<int>(top), mesh_.V.col(top) + Eigen::Vector3d(0.2, 0, 0));
  c.normal = Eigen::Vector3d::UnitZ();
  DeformationState state = DeformationState::Identity(graph_.num_nodes());
  ASSERT_TRUE(SolveEmbeddedDeformation(graph_, std::vector<PointConstraint>{c}, {}, &state).usable);
  EXPECT_LT((DeformPoints(graph_, weights_, mesh_.V, state) - mesh_.V).cwiseAbs().maxCoeff(), 1e-6);
}

}  // namespace
}  // namespace vb::morph
