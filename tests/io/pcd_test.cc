#include "io/pcd.h"

#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cmath>
#include <cstring>

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
  const geometry::PointCloud cloud = ReadPcd(file);
  ASSERT_EQ(cloud.size(), 2);
  EXPECT_EQ(cloud.points.col(1), Eigen::Vector3d(1, 2, 3));
  EXPECT_FALSE(cloud.has_normals());
}

// The binary bodies are read here, not by PCL: PCL's own files, with a colour field and
// padding between the fields read, in both binary encodings, come back exactly.
TEST(PcdTest, ReadsPclsBinaryAndCompressedFilesWithPaddingAndOtherFields) {
  test::TempDir dir;
  pcl::PointCloud<pcl::PointXYZRGBNormal> in;
  for (int i = 0; i < 50; ++i) {
    pcl::PointXYZRGBNormal p;
    p.x = 0.5f * static_cast<float>(i);
    p.y = -1.0f - static_cast<float>(i);
    p.z = 0.25f;
    p.r = static_cast<std::uint8_t>(i);
    p.g = p.b = 7;
    p.normal_x = 0.6f;
    p.normal_y = 0.0f;
    p.normal_z = -0.8f;
    p.curvature = 0.1f;
    in.push_back(p);
  }
  in[3].x = std::nanf("");  // dropped
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir / "b.pcd").string(), in), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinaryCompressed((dir / "c.pcd").string(), in), 0);
  for (const char* name : {"b.pcd", "c.pcd"}) {
    const geometry::PointCloud cloud = ReadPcd(dir / name);
    ASSERT_EQ(cloud.size(), 49) << name;
    ASSERT_TRUE(cloud.has_normals()) << name;
    EXPECT_EQ(cloud.points.col(3), Eigen::Vector3d(2.0, -5.0, 0.25)) << name;  // point 4
    EXPECT_EQ(cloud.points.col(48), Eigen::Vector3d(24.5, -50.0, 0.25)) << name;
    EXPECT_FLOAT_EQ(static_cast<float>(cloud.normals(2, 10)), -0.8f) << name;
  }
}

// A compressed body may not decompress to more than a file may hold (1 GiB): a small file
// cannot ask for gigabytes.
TEST(PcdTest, RefusesACompressedBodyLargerThanTheFileLimitUncompressed) {
  test::TempDir dir;
  std::string body(1 << 20, '\0');
  const std::uint32_t sizes[2] = {1000, 3000000 * 12};
  std::memcpy(body.data(), sizes, 8);
  const auto file = dir.Write("big.pcd",
                              "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                              "WIDTH 3000000\nHEIGHT 1\nPOINTS 3000000\nDATA binary_compressed\n" +
                                  body);
  ReadLimits limits;
  limits.max_file_bytes = 16 << 20;
  try {
    ReadPcd(file, limits);
    FAIL() << "read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("decompresses to more than the file limit of 16777216"),
              std::string::npos)
        << e.what();
  }
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
