#include "io/obj.h"

#include <gtest/gtest.h>

#include "io/error.h"
#include "tests/support/temp_dir.h"

namespace vb::io {
namespace {

TEST(ObjTest, ReadsAllCornerFormsAndNegativeIndices) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh =
      ReadObj(dir.Write("forms.obj",
                        "o thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 1.0\nvt 0 0\ns off\n"
                        "f 1/1 2/1 3/1\nf -4 -2 -1\n"
                        "f 1 3 4\n"));
  ASSERT_EQ(mesh.num_vertices(), 4);
  ASSERT_EQ(mesh.num_faces(), 3);
  EXPECT_EQ(mesh.F.col(0), Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.F.col(1), Eigen::Vector3i(0, 2, 3));
  EXPECT_FALSE(mesh.has_normals());
}

TEST(ObjTest, KeepsNormalsOnlyWhenTheyArePerVertex) {
  test::TempDir dir;
  const geometry::TriangleMesh per_vertex =
      ReadObj(dir.Write("pv.obj",
                        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 -1\n"
                        "f 1//2 2//1 3//1\n"));
  ASSERT_TRUE(per_vertex.has_normals());
  EXPECT_EQ(per_vertex.N.col(0), Eigen::Vector3d(0, 0, -1));
  EXPECT_EQ(per_vertex.N.col(1), Eigen::Vector3d(0, 0, 1));
  const geometry::TriangleMesh per_corner =
      ReadObj(dir.Write("pc.obj",
                        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvn 0 0 1\nvn 0 0 -1\n"
                        "f 1//1 2//1 3//1\nf 2//2 4//2 3//2\n"));
  EXPECT_FALSE(per_corner.has_normals());
}

TEST(ObjTest, TriangulatesPolygons) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh =
      ReadObj(dir.Write("pent.obj", "v 0 0 0\nv 1 0 0\nv 2 1 0\nv 1 2 0\nv 0 1 0\nf 1 2 3 4 5\n"));
  EXPECT_EQ(mesh.num_faces(), 3);
}

TEST(ObjTest, RejectsBadContentNamingFileAndLine) {
  test::TempDir dir;
  auto expect = [&](const char* name, const char* text, const char* fragment) {
    try {
      ReadObj(dir.Write(name, text));
      ADD_FAILURE() << "no error for " << name;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  expect("future.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\nv 0 1 0\n", ":3: vertex index 3");
  expect("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", ":4: vertex index 0");
  expect("text.obj", "v 0 zero 0\n", ":1: vertex coordinate");
  expect("short.obj", "v 0 0\n", ":1: missing vertex coordinate");
  expect("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n", ":3: face has 2 corners");
  expect("normal.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n", ":4: normal index 1");
}

}  // namespace
}  // namespace vb::io
