#include "geometry/plane_cut.h"

#include <gtest/gtest.h>

#include <numbers>

#include "geometry/mesh_measures.h"
#include "tests/support/test_meshes.h"

namespace vb::geometry {
namespace {

Plane MakePlane(Eigen::Vector3d point, Eigen::Vector3d normal) {
  return Plane{point, normal.normalized()};
}

TEST(PlaneSectionTest, BoxSectionIsOneClosedLoopOnThePlane) {
  const TriangleMesh box = test::Box();
  const Plane plane = MakePlane({0.5, 0.5, 0.3}, {0.1, 0.2, 1.0});
  const std::vector<SectionLoop> loops = PlaneSection(box, plane);
  ASSERT_EQ(loops.size(), 1u);
  EXPECT_TRUE(loops[0].closed);
  EXPECT_GE(loops[0].points.size(), 4u);
  for (const SurfacePoint& p : loops[0].points) {
    EXPECT_NEAR(plane.SignedDistance(Evaluate(box, p)), 0.0, 1e-12);
    EXPECT_NEAR(p.barycentric.sum(), 1.0, 1e-12);
  }
}

TEST(PlaneSectionTest, CountsOneLoopPerPieceAndNoneWhenMissing) {
  // Two separate spheres cut through both centres: two loops.
  TriangleMesh a = test::Sphere(1.0, 2);
  TriangleMesh two;
  two.V.resize(3, 2 * a.num_vertices());
  two.V << a.V, (a.V.array().colwise() + Eigen::Array3d(3, 0, 0)).matrix();
  two.F.resize(3, 2 * a.num_faces());
  two.F << a.F, (a.F.array() + a.num_vertices()).matrix();
  EXPECT_EQ(PlaneSection(two, MakePlane({0, 0, 0.1}, {0, 0, 1})).size(), 2u);
  EXPECT_TRUE(PlaneSection(two, MakePlane({0, 0, 5}, {0, 0, 1})).empty());
}

TEST(MeasurePartsTest, ParallelCutsOfABox) {
  const TriangleMesh box = test::Box(1.0, 2.0, 4.0);
  const std::vector<Plane> cuts = {MakePlane({0, 0, 3}, {0, 0, 1}),
                                   MakePlane({0, 0, 1}, {0, 0, 1})};
  const std::vector<PartMeasure> parts = MeasureParts(box, cuts);
  ASSERT_EQ(parts.size(), 3u);
  EXPECT_NEAR(parts[0].volume, 2.0, 1e-12);
  EXPECT_NEAR(parts[1].volume, 4.0, 1e-12);
  EXPECT_NEAR(parts[2].volume, 2.0, 1e-12);
  EXPECT_NEAR(parts[0].area, 2.0 + 1 * (2 * 1 + 2 * 2), 1e-12);  // top face + four side strips
  EXPECT_NEAR(parts[1].area, 2 * (2 * 1 + 2 * 2), 1e-12);
}

TEST(MeasurePartsTest, TiltedCutsThatMeetOutsideTheBodySumToTheWhole) {
  const TriangleMesh sphere = test::Sphere(1.0, 4);
  const double total = SignedVolume(sphere);
  // Neighbouring planes tilted towards each other; their common line lies outside the sphere.
  const std::vector<Plane> cuts = {MakePlane({0, 0, 0.5}, {0.2, 0, 1}),
                                   MakePlane({0, 0, -0.1}, {-0.15, 0.1, 1}),
                                   MakePlane({0, 0, -0.6}, {0.1, -0.2, 1})};
  const std::vector<PartMeasure> parts = MeasureParts(sphere, cuts);
  double sum = 0.0;
  for (const PartMeasure& p : parts) {
    EXPECT_GT(p.volume, 0.0);
    sum += p.volume;
  }
  EXPECT_NEAR(sum, total, 1e-9 * total);
  double area = 0.0;
  for (const PartMeasure& p : parts) area += p.area;
  EXPECT_NEAR(area, SurfaceArea(sphere), 1e-9);
}

TEST(MeasurePartsTest, CapOfASphereMatchesTheClosedForm) {
  const TriangleMesh sphere = test::Sphere(1.0, 5);
  const double h = 0.4;  // cap height above z = 0.6
  const std::vector<PartMeasure> parts =
      MeasureParts(sphere, std::vector<Plane>{MakePlane({0, 0, 1 - h}, {0, 0, 1})});
  const double cap = std::numbers::pi * h * h * (3 - h) / 3;
  EXPECT_NEAR(parts[0].volume, cap, 0.01 * cap);
}

}  // namespace
}  // namespace vb::geometry
