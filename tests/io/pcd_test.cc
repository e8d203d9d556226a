#include "io/pcd.h"

#include <gtest/gtest.h>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::io {
namespace {

TEST(PcdTest, ReadsAsciiAndDropsInvalidPoints) {
  test::TempDir dir;
  const auto file =
      dir.Write("a.pcd",
                "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
                "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n0 0 0\nnan nan nan\n1 2 3\n");
  const PointCloud cloud = ReadPcd(file);
  ASSERT_EQ(cloud.size(), 2);
  EXPECT_EQ(cloud.points.col(1), Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(cloud.has_normals());
}

TEST(PcdTest, RejectsHeaderClaimingMorePointsThanTheFileHolds) {
  test::TempDir dir;
  const auto file =
      dir.Write("huge.pcd",
                "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH "
                "1000000000\nHEIGHT 1000\n"
                "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1000000000000\nDATA binary\n\x01\x02\x03");
  try {
    ReadPcd(file);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("huge.pcd"), std::string::npos) << e.what();
  }
}

TEST(PcdTest, RejectsCloudsWithoutCoordinates) {
  test::TempDir dir;
  const auto file = dir.Write("rgb.pcd",
                              "VERSION .7\nFIELDS rgb\nSIZE 4\nTYPE F\nCOUNT 1\nWIDTH 1\nHEIGHT 1\n"
                              "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1\nDATA ascii\n0\n");
  EXPECT_THROW(ReadPcd(file), InputError);
  EXPECT_THROW(ReadPcd(dir.Write("garbage.pcd", "not a pcd file\n")), InputError);
}

}  // namespace
}  // namespace vb::io
