#include "io/mesh_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "geometry/mesh_measures.h"
#include "io/error.h"
#include "tests/support/temp_dir.h"
#include "tests/support/test_meshes.h"

namespace vb::io {
namespace {

struct MeshCase {
  const char* file;
  PlyEncoding encoding;
  bool normals;
};

class MeshRoundTripTest : public ::testing::TestWithParam<MeshCase> {};

// Irregular coordinates so any reordering or rounding shows.
geometry::TriangleMesh TestMesh(bool normals) {
  geometry::TriangleMesh mesh = test::Sphere(0.7, 2);
  for (int i = 0; i < mesh.num_vertices(); ++i)
    mesh.V.col(i) += Eigen::Vector3d(0.1 * i, -1.0 / 3.0, 1e-7 * i * i);
  if (normals) mesh.N = geometry::VertexNormals(mesh);
  return mesh;
}

TEST_P(MeshRoundTripTest, KeepsVertexOrderFacesAndNormalsExactly) {
  const MeshCase& c = GetParam();
  test::TempDir dir;
  const geometry::TriangleMesh mesh = TestMesh(c.normals);
  WriteMesh(dir / c.file, mesh, {c.encoding});
  const geometry::TriangleMesh back = ReadMesh(dir / c.file);
  ASSERT_EQ(back.num_vertices(), mesh.num_vertices());
  ASSERT_EQ(back.num_faces(), mesh.num_faces());
  EXPECT_EQ(back.V, mesh.V);
  EXPECT_EQ(back.F, mesh.F);
  ASSERT_EQ(back.has_normals(), c.normals);
  if (c.normals) {
    EXPECT_EQ(back.N, mesh.N);
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllMeshFormats, MeshRoundTripTest,
    ::testing::Values(MeshCase{"m.ply", PlyEncoding::kBinaryLittleEndian, false},
                      MeshCase{"m.ply", PlyEncoding::kBinaryLittleEndian, true},
                      MeshCase{"m.ply", PlyEncoding::kAscii, false},
                      MeshCase{"m.ply", PlyEncoding::kAscii, true},
                      MeshCase{"m.off", PlyEncoding::kAscii, false},
                      MeshCase{"m.off", PlyEncoding::kAscii, true},
                      MeshCase{"m.obj", PlyEncoding::kAscii, false},
                      MeshCase{"m.obj", PlyEncoding::kAscii, true}),
    [](const ::testing::TestParamInfo<MeshCase>& info) {
      std::string name = info.param.file + 2;  // extension
      if (name == "ply") name += info.param.encoding == PlyEncoding::kAscii ? "_ascii" : "_binary";
      return name + (info.param.normals ? "_normals" : "_plain");
    });

class CloudRoundTripTest : public ::testing::TestWithParam<const char*> {};

TEST_P(CloudRoundTripTest, KeepsPointsAndNormals) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh = TestMesh(true);
  geometry::PointCloud cloud{mesh.V, mesh.N};
  WriteCloud(dir / GetParam(), cloud);
  const geometry::PointCloud back = ReadCloud(dir / GetParam());
  ASSERT_EQ(back.size(), cloud.size());
  ASSERT_TRUE(back.has_normals());
  // PCD stores float32; the text and PLY formats are exact.
  const double tolerance = FormatFromPath(GetParam()) == FileFormat::kPcd ? 1e-6 : 0.0;
  EXPECT_LE((back.points - cloud.points).cwiseAbs().maxCoeff(), tolerance);
  EXPECT_LE((back.normals - cloud.normals).cwiseAbs().maxCoeff(), tolerance);
}

INSTANTIATE_TEST_SUITE_P(AllCloudFormats, CloudRoundTripTest,
                         ::testing::Values("c.ply", "c.off", "c.obj", "c.xyz", "c.pcd", "C.PCD"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           return std::string(info.param[0] == 'C' ? "upper_" : "") +
                                  (info.param + 2);
                         });

// A scanner's file may carry zero-length or NaN normals (a real lamb scan had only zeros):
// they are never trusted. All of the file's normals are dropped, with a warning naming it.
class InvalidNormalsTest : public ::testing::TestWithParam<const char*> {};

TEST_P(InvalidNormalsTest, AreDroppedWithAWarningNamingTheFile) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh = TestMesh(true);
  for (const double bad : {0.0, std::nan("")}) {
    geometry::PointCloud cloud{mesh.V, mesh.N};
    cloud.normals.col(3).setConstant(bad);
    WriteCloud(dir / GetParam(), cloud);
    std::vector<std::string> warnings;
    const geometry::PointCloud back = ReadCloud(dir / GetParam(), {}, &warnings);
    EXPECT_EQ(back.size(), cloud.size());
    EXPECT_FALSE(back.has_normals());
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find((dir / GetParam()).string()), std::string::npos) << warnings[0];
    EXPECT_NE(warnings[0].find("1 of " + std::to_string(cloud.size()) + " normals"),
              std::string::npos)
        << warnings[0];
  }
}

TEST_P(InvalidNormalsTest, OthersAreRescaledToUnitLength) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh = TestMesh(true);
  geometry::PointCloud cloud{mesh.V, 3.0 * mesh.N};
  WriteCloud(dir / GetParam(), cloud);
  std::vector<std::string> warnings;
  const geometry::PointCloud back = ReadCloud(dir / GetParam(), {}, &warnings);
  EXPECT_TRUE(warnings.empty());
  ASSERT_TRUE(back.has_normals());
  EXPECT_LT((back.normals - mesh.N).cwiseAbs().maxCoeff(), 1e-6);
}

INSTANTIATE_TEST_SUITE_P(AllCloudFormats, InvalidNormalsTest,
                         ::testing::Values("c.ply", "c.off", "c.obj", "c.xyz", "c.pcd"),
                         [](const ::testing::TestParamInfo<const char*>& info) {
                           return std::string(info.param + 2);
                         });

TEST(MeshIoTest, ReadMeshDropsInvalidNormalsToo) {
  test::TempDir dir;
  geometry::TriangleMesh mesh = TestMesh(true);
  mesh.N.setZero();
  WriteMesh(dir / "m.ply", mesh);
  std::vector<std::string> warnings;
  EXPECT_FALSE(ReadMesh(dir / "m.ply", {}, &warnings).has_normals());
  EXPECT_EQ(warnings.size(), 1u);
}

TEST(MeshIoTest, ReadCloudAcceptsMeshFiles) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh = test::Box();
  WriteMesh(dir / "box.off", mesh);
  EXPECT_EQ(ReadCloud(dir / "box.off").points, mesh.V);
}

TEST(MeshIoTest, ReadMeshOrCloudKeepsAMeshsFacesAndReadsACloudWithout) {
  test::TempDir dir;
  const geometry::TriangleMesh mesh = test::Box();
  WriteMesh(dir / "box.ply", mesh);
  const geometry::TriangleMesh back = ReadMeshOrCloud(dir / "box.ply");
  EXPECT_EQ(back.V, mesh.V);
  EXPECT_EQ(back.F, mesh.F);
  geometry::PointCloud cloud;
  cloud.points = mesh.V;
  for (const char* name : {"box_cloud.ply", "box.xyz", "box.pcd"}) {
    WriteCloud(dir / name, cloud);
    const geometry::TriangleMesh points = ReadMeshOrCloud(dir / name);
    EXPECT_EQ(points.num_faces(), 0) << name;
    EXPECT_TRUE(points.V.isApprox(mesh.V, 1e-6)) << name;
  }
  EXPECT_THROW(ReadMeshOrCloud(dir.Write("empty.xyz", "")), InputError);
}

TEST(MeshIoTest, RefusesUnknownExtensionNamingIt) {
  test::TempDir dir;
  const auto file = dir.Write("mesh.stl", "solid x\n");
  try {
    ReadMesh(file);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mesh.stl"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find(".stl"), std::string::npos);
  }
}

TEST(MeshIoTest, RefusesCloudWhereMeshIsNeeded) {
  test::TempDir dir;
  WriteCloud(dir / "p.xyz", geometry::PointCloud{test::Box().V, {}});
  EXPECT_THROW(ReadMesh(dir / "p.xyz"), InputError);
  WriteCloud(dir / "p.ply", geometry::PointCloud{test::Box().V, {}});
  EXPECT_THROW(ReadMesh(dir / "p.ply"), InputError);
  EXPECT_THROW(WriteMesh(dir / "m.pcd", test::Box()), InputError);
}

TEST(MeshIoTest, RefusesMissingAndEmptyFiles) {
  test::TempDir dir;
  EXPECT_THROW(ReadMesh(dir / "absent.ply"), InputError);
  EXPECT_THROW(ReadCloud(dir.Write("empty.xyz", "")), InputError);
  EXPECT_THROW(ReadMesh(dir.Write("empty.obj", "# nothing\n")), InputError);
}

TEST(MeshIoTest, RefusesFilesAboveTheSizeLimit) {
  test::TempDir dir;
  WriteMesh(dir / "box.off", test::Box());
  ReadLimits limits;
  limits.max_file_bytes = 16;
  EXPECT_THROW(ReadMesh(dir / "box.off", limits), InputError);
}

}  // namespace
}  // namespace vb::io
