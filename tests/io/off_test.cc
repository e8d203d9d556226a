#include "io/off.h"

#include <gtest/gtest.h>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::io {
namespace {

void ExpectRejected(const std::filesystem::path& file,
                    std::initializer_list<const char*> fragments) {
  try {
    ReadOff(file);
    ADD_FAILURE() << "no error for " << file;
  } catch (const InputError& e) {
    for (const char* fragment : fragments) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
          << e.what() << " lacks " << fragment;
    }
  }
}

TEST(OffTest, ReadsCountsOnTheKeywordLineCommentsAndPolygons) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh =
      ReadOff(dir.Write("q.off", "OFF 4 1 0\n# corners\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 3 2 1 0\n"));
  ASSERT_EQ(mesh.num_faces(), 2);
  EXPECT_EQ(mesh.F.col(0), Eigen::Vector3i(3, 2, 1));
  EXPECT_EQ(mesh.F.col(1), Eigen::Vector3i(3, 1, 0));
}

TEST(OffTest, ReadsNoffNormals) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh =
      ReadOff(dir.Write("n.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n"));
  ASSERT_TRUE(mesh.has_normals());
  EXPECT_EQ(mesh.N.col(2), Eigen::Vector3d(0, 0, 1));
}

TEST(OffTest, SkipsColours) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh = ReadOff(dir.Write(
      "c.off",
      "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2 9 9 9\n"));
  EXPECT_EQ(mesh.V.col(1), Eigen::Vector3d(1, 0, 0));
  EXPECT_EQ(mesh.num_faces(), 1);
}

TEST(OffTest, RejectsBadContentNamingFileAndLine) {
  test::TempDir dir;
  ExpectRejected(dir.Write("magic.off", "PLY\n"), {"magic.off:1", "'OFF'"});
  ExpectRejected(dir.Write("short_face.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n"),
                 {"short_face.off:6", "missing vertex index"});
  ExpectRejected(dir.Write("huge.off", "OFF\n4000000 1 0\n0 0 0\n"),
                 {"huge.off:2", "4000000 vertices", "do not fit"});
  ExpectRejected(dir.Write("over.off", "OFF\n1000000000000 1 0\n0 0 0\n"),
                 {"over.off", "1000000000000 vertices", "limit of 5000000"});
  ExpectRejected(dir.Write("neg.off", "OFF\n-3 1 0\n"), {"neg.off:2"});
  ExpectRejected(dir.Write("coord.off", "OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n"),
                 {"coord.off:4", "'x'"});
  ExpectRejected(dir.Write("index.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"),
                 {"index.off:6", "vertex index 3"});
  ExpectRejected(
      dir.Write("short.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n# the third vertex is missing\n"),
      {"short.off", "2 of 3 vertices"});
  ExpectRejected(dir.Write("tiny.off", "OFF\n3 1 0\n0 0 0\n"), {"tiny.off:2", "do not fit"});
  ExpectRejected(dir.Write("poly.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n99999 0 1 2\n"),
                 {"poly.off:6", "99999"});
  ExpectRejected(dir.Write("inf.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n"),
                 {"inf.off:5", "not finite"});
}

}  // namespace
}  // namespace vb::io
