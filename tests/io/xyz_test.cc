#include "io/xyz.h"

#include <gtest/gtest.h>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::io {
namespace {

TEST(XyzTest, ReadsPointsWithAndWithoutNormals) {
  test::TempDir dir;
  const geometry::PointCloud plain = ReadXyz(dir.Write("a.xyz", "# scan\n0 0 0\n1 2 3\n\n4 5 6\n"));
  EXPECT_EQ(plain.size(), 3);
  EXPECT_FALSE(plain.has_normals());
  EXPECT_EQ(plain.points.col(2), Eigen::Vector3d(4, 5, 6));
  const geometry::PointCloud with = ReadXyz(dir.Write("b.xyz", "0 0 0 0 0 1\n1 1 1 1 0 0\n"));
  ASSERT_TRUE(with.has_normals());
  EXPECT_EQ(with.normals.col(1), Eigen::Vector3d(1, 0, 0));
}

TEST(XyzTest, RejectsRaggedAndNonNumericLines) {
  test::TempDir dir;
  EXPECT_THROW(ReadXyz(dir.Write("ragged.xyz", "0 0 0\n1 1 1 0 0 1\n")), InputError);
  EXPECT_THROW(ReadXyz(dir.Write("four.xyz", "0 0 0 0\n")), InputError);
  try {
    ReadXyz(dir.Write("word.xyz", "0 0 0\n1 one 1\n"));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("word.xyz:2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vb::io
