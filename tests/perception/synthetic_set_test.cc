#include "perception/synthetic_set.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "io/annotations.h"
#include "io/error.h"
#include "io/mesh_io.h"
#include "tests/support/temp_dir.h"

namespace vb::perception {
namespace {

std::string Bytes(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(SyntheticSetTest, WritesALoadableSetWithGroundTruth) {
  test::TempDir dir;
  SyntheticSetOptions options;
  options.out_dir = dir / "set";
  options.count = 2;
  options.seed = 11;
  options.sigma_mm = 2.0;
  options.cloud = true;
  options.missing_regions = true;
  options.cloud_points = 3000;
  const SyntheticSetSummary summary = WriteSyntheticSet(options);
  ASSERT_EQ(summary.targets.size(), 2u);
  EXPECT_NE(FormatSummary(summary).find("target_001"), std::string::npos);

  const geometry::TriangleMesh tmpl = io::ReadMesh(options.out_dir / "template.ply");
  const io::Annotations annotations =
      io::LoadAnnotations(options.out_dir / "template_annotations.yaml");
  EXPECT_NO_THROW(io::CheckAnnotationsFit(annotations, tmpl, "template.ply"));
  for (const char* name : {"target_000", "target_001"}) {
    const std::string base = name;
    const geometry::TriangleMesh noisy = io::ReadMesh(options.out_dir / (base + ".ply"));
    const geometry::TriangleMesh truth = io::ReadMesh(options.out_dir / (base + "_truth.ply"));
    EXPECT_EQ(noisy.F, tmpl.F);
    EXPECT_EQ(truth.F, tmpl.F);
    const double moved = (noisy.V - truth.V).colwise().norm().mean();
    EXPECT_GT(moved, 0.0005);  // E|N(0, 2 mm)| is 1.6 mm
    EXPECT_LT(moved, 0.004);
    const geometry::PointCloud cloud = io::ReadCloud(options.out_dir / (base + "_cloud.ply"));
    EXPECT_GT(cloud.size(), 1000);
    EXPECT_TRUE(std::filesystem::exists(options.out_dir / (base + "_truth.yaml")));
  }
  EXPECT_TRUE(std::filesystem::exists(options.out_dir / "template_skeleton.yaml"));
  EXPECT_TRUE(std::filesystem::exists(options.out_dir / "synthetic_set.yaml"));
}

TEST(SyntheticSetTest, SameSeedSameBytesOtherSeedOtherTargets) {
  test::TempDir dir;
  SyntheticSetOptions options;
  options.count = 1;
  options.sigma_mm = 4.0;
  options.out_dir = dir / "a";
  WriteSyntheticSet(options);
  options.out_dir = dir / "b";
  WriteSyntheticSet(options);
  options.out_dir = dir / "c";
  options.seed = 2;
  WriteSyntheticSet(options);
  for (const char* file :
       {"template.ply", "template_annotations.yaml", "target_000.ply", "target_000_truth.yaml"}) {
    EXPECT_EQ(Bytes(dir / "a" / file), Bytes(dir / "b" / file)) << file;
  }
  EXPECT_EQ(Bytes(dir / "a" / "template.ply"), Bytes(dir / "c" / "template.ply"));
  EXPECT_NE(Bytes(dir / "a" / "target_000.ply"), Bytes(dir / "c" / "target_000.ply"));
}

TEST(SyntheticSetTest, RejectsBadOptionsNamingThem) {
  auto expect = [](SyntheticSetOptions options, const char* option) {
    try {
      options.Validate();
      ADD_FAILURE() << "no error for " << option;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(option), std::string::npos) << e.what();
    }
  };
  SyntheticSetOptions good;
  good.out_dir = "/tmp/unused";
  EXPECT_NO_THROW(good.Validate());
  SyntheticSetOptions o = good;
  o.count = 0;
  expect(o, "--count");
  o = good;
  o.sigma_mm = -1;
  expect(o, "--sigma-mm");
  o = good;
  o.sigma_mm = std::numeric_limits<double>::quiet_NaN();
  expect(o, "--sigma-mm");
  o = good;
  o.missing_regions = true;
  expect(o, "--missing");
  o = good;
  o.out_dir.clear();
  expect(o, "--out");
}

}  // namespace
}  // namespace vb::perception
