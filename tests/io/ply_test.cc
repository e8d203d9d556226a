#include "io/ply.h"

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>

#include "io/error.h"
#include "tests/support/temp_dir.h"
#include "tests/support/test_meshes.h"

namespace vb::io {
namespace {

// Expects ReadPly to throw InputError whose message contains every fragment.
void ExpectRejected(const std::filesystem::path& file,
                    std::initializer_list<const char*> fragments) {
  try {
    ReadPly(file);
    ADD_FAILURE() << "no error for " << file;
  } catch (const InputError& e) {
    for (const char* fragment : fragments) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
          << e.what() << " lacks " << fragment;
    }
  }
}

const char* kAsciiHeader =
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float "
    "z\n"
    "element face 2\nproperty list uchar int vertex_indices\nend_header\n";

TEST(PlyTest, ReadsQuadsAsTwoTrianglesAndIgnoresExtraProperties) {
  test::TempDir dir;
  const auto file = dir.Write(
      "quad.ply",
      "ply\nformat ascii 1.0\ncomment a quad\nelement vertex 4\nproperty float x\nproperty float "
      "y\n"
      "property float z\nproperty uchar red\nelement face 1\nproperty list uchar int "
      "vertex_indices\n"
      "property float quality\nend_header\n0 0 0 9\n1 0 0 9\n1 1 0 9\n0 1 0 9\n4 0 1 2 3 0.5\n");
  const geometry::TriangleMesh mesh = ReadPly(file);
  ASSERT_EQ(mesh.num_vertices(), 4);
  ASSERT_EQ(mesh.num_faces(), 2);
  EXPECT_EQ(mesh.F.col(0), Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.F.col(1), Eigen::Vector3i(0, 2, 3));
  EXPECT_FALSE(mesh.has_normals());
}

TEST(PlyTest, ReadsBigEndianBinary) {
  test::TempDir dir;
  std::string body =
      "ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nproperty float "
      "y\nproperty float z\nend_header\n";
  for (float v : {1.5f, -2.0f, 0.25f}) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, 4);
    for (int shift = 24; shift >= 0; shift -= 8)
      body.push_back(static_cast<char>((bits >> shift) & 0xFF));
  }
  const geometry::TriangleMesh mesh = ReadPly(dir.Write("be.ply", body));
  EXPECT_EQ(mesh.V.col(0), Eigen::Vector3d(1.5, -2.0, 0.25));
}

TEST(PlyTest, RejectsHeaderClaimingMoreVerticesThanTheFileHolds) {
  test::TempDir dir;
  const auto file = dir.Write(
      "huge.ply",
      "ply\nformat binary_little_endian 1.0\nelement vertex 4000000\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n\x01\x02");
  ExpectRejected(file, {"huge.ply", "4000000 vertex elements", "the file has"});
  // Over the vertex limit, refused before the file's size is even compared.
  const auto over = dir.Write(
      "over.ply",
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n\x01\x02");
  ExpectRejected(over, {"over.ply", "1000000000000 vertices", "limit of 5000000"});
}

TEST(PlyTest, RejectsTruncatedBinaryNamingTheElement) {
  test::TempDir dir;
  const geometry::TriangleMesh box = test::Box();
  WritePly(dir / "box.ply", box, PlyEncoding::kBinaryLittleEndian);
  std::ifstream in(dir / "box.ply", std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Header plus all vertices and half the faces: the counts still fit the size check.
  ExpectRejected(dir.Write("cut.ply", bytes.substr(0, bytes.size() - 6 * 13)), {"cut.ply", "face"});
}

TEST(PlyTest, RejectsOutOfRangeIndexNamingFaceAndLine) {
  test::TempDir dir;
  const auto file =
      dir.Write("bad_index.ply",
                std::string(kAsciiHeader) + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 7\n");
  ExpectRejected(file, {"bad_index.ply", "face 1", "7", "[0, 4)"});
}

TEST(PlyTest, RejectsNonFiniteCoordinates) {
  test::TempDir dir;
  ExpectRejected(dir.Write("nan.ply", std::string(kAsciiHeader) +
                                          "0 0 0\n1 nan 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n"),
                 {"nan.ply", "vertex 1"});
  ExpectRejected(dir.Write("word.ply", std::string(kAsciiHeader) +
                                           "0 0 0\n1 zero 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n"),
                 {"word.ply", "vertex 1"});
}

TEST(PlyTest, RejectsDegenerateAndOversizedPolygons) {
  test::TempDir dir;
  ExpectRejected(dir.Write("two.ply", std::string(kAsciiHeader) +
                                          "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 1\n3 0 2 3\n"),
                 {"two.ply", "face 0", "2 corners"});
  ExpectRejected(dir.Write("repeat.ply", std::string(kAsciiHeader) +
                                             "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 1\n3 0 2 3\n"),
                 {"repeat.ply", "repeats vertex 1"});
}

TEST(PlyTest, RejectsFilesThatAreNotPlyOrLackCoordinates) {
  test::TempDir dir;
  ExpectRejected(dir.Write("text.ply", "hello world\n"), {"text.ply"});
  ExpectRejected(dir.Write("noz.ply",
                           "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty "
                           "float y\nend_header\n1 2\n"),
                 {"noz.ply", "x, y or z"});
  ExpectRejected(dir.Write("short.ply", std::string(kAsciiHeader) + "0 0 0\n1 0 0\n"),
                 {"short.ply"});
}

}  // namespace
}  // namespace vb::io
