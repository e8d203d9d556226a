#include "morph/embedded_deformation.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

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
