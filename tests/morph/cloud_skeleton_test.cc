#include "morph/cloud_skeleton.h"

#include <gtest/gtest.h>

#include <random>

#include "geometry/mesh_measures.h"
#include "io/error.h"
#include "tests/support/implicit_shapes.h"

namespace vb::morph {
namespace {

FeatureNodes Features(const Eigen::Matrix3Xd& points) {
  const double size = geometry::BoundingBoxDiagonal(points);
  return ExtractFeatureNodes(CloudSkeleton(points), {.min_branch_length = 0.09 * size,
                                                     .junction_merge_distance = 0.08 * size});
}

// Each terminal lies near the end of one arm, every arm has one.
void ExpectArmEnds(const FeatureNodes& f) {
  ASSERT_EQ(f.num_terminals(), 3);
  EXPECT_EQ(f.num_junctions(), 1);
  std::vector<bool> arm_found(3, false);
  for (int t = 0; t < 3; ++t) {
    for (int k = 0; k < 3; ++k) {
      const double angle = 2.0 * M_PI * k / 3.0 + 0.3;
      const Eigen::Vector3d end(std::cos(angle), std::sin(angle), 0.1 * k);
      if ((f.terminals.col(t) - end).norm() < 0.2) arm_found[static_cast<std::size_t>(k)] = true;
    }
  }
  EXPECT_EQ(arm_found, std::vector<bool>(3, true));
  EXPECT_LT(f.junctions.col(0).norm(), 0.25) << "the arms meet at the origin";
}

TEST(CloudSkeletonTest, FindsTheArmsOfAY) {
  const geometry::TriangleMesh y = test::YShape();
  ExpectArmEnds(Features(y.V));
}

TEST(CloudSkeletonTest, CopesWithNormalNoise) {
  const geometry::TriangleMesh y = test::YShape();
  const Eigen::Matrix3Xd normals = geometry::VertexNormals(y);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(
      0.0, 0.015);  // about 1.3 % of the size, like 16 mm on a carcass
  Eigen::Matrix3Xd noisy = y.V;
  for (Eigen::Index i = 0; i < noisy.cols(); ++i) noisy.col(i) += noise(rng) * normals.col(i);
  ExpectArmEnds(Features(noisy));
}

TEST(CloudSkeletonTest, BridgesAMissingRegion) {
  const geometry::TriangleMesh y = test::YShape();
  // Cut a band out of one arm: the cloud falls into two pieces.
  const double angle = 0.3;
  const Eigen::Vector3d arm(std::cos(angle), std::sin(angle), 0.0);
  std::vector<int> kept;
  for (Eigen::Index i = 0; i < y.V.cols(); ++i) {
    const double along = y.V.col(i).dot(arm);
    if (along < 0.45 || along > 0.55) kept.push_back(static_cast<int>(i));
  }
  Eigen::Matrix3Xd partial(3, static_cast<Eigen::Index>(kept.size()));
  for (std::size_t k = 0; k < kept.size(); ++k)
    partial.col(static_cast<Eigen::Index>(k)) = y.V.col(kept[k]);
  ExpectArmEnds(Features(partial));
}

TEST(CloudSkeletonTest, RefusesTinyOrFlatInput) {
  EXPECT_THROW(CloudSkeleton(Eigen::Matrix3Xd::Random(3, 10)), InputError);
  EXPECT_THROW(CloudSkeleton(Eigen::Matrix3Xd::Zero(3, 100)), InputError);
}

// Enough points, but on a few spots: 49 copies of one point and one apart, or three spots of
// 20. An error that says why, not a read past the skeleton's arrays.
TEST(CloudSkeletonTest, RefusesAFewSpotsWithAnErrorNotACrash) {
  Eigen::Matrix3Xd two = Eigen::Matrix3Xd::Zero(3, 50);
  two.col(49) = Eigen::Vector3d(1, 0, 0);
  Eigen::Matrix3Xd three = Eigen::Matrix3Xd::Zero(3, 60);
  three.middleCols(20, 20).colwise() = Eigen::Vector3d(1, 0, 0);
  three.rightCols(20).colwise() = Eigen::Vector3d(0, 1, 0);
  for (const Eigen::Matrix3Xd* cloud : {&two, &three}) {
    try {
      CloudSkeleton(*cloud);
      ADD_FAILURE() << cloud->cols() << " points: no error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("no body to follow"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace vb::morph
