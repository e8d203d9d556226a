// The shape benchmark's ground truth: third-party models posed by their own rigs, wrapped
// closed, and carried vertex by vertex.
#include "tools/shape_set/shape_set.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <ostream>
#include <string>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "io/error.h"
#include "morph/template_model.h"

namespace vb::tools {
namespace {

constexpr double kPi = std::numbers::pi;

// A straight bar of points; the last @p share of it turned by @p degrees about the joint.
Eigen::Matrix3Xd Bar(double share, double degrees) {
  const int n = 4000;
  Eigen::Matrix3Xd P(3, n);
  for (int i = 0; i < n; ++i) {
    const double x = 2.0 * i / (n - 1);
    P.col(i) = Eigen::Vector3d(x, 0.05 * std::cos(i * 2.4), 0.05 * std::sin(i * 2.4));
  }
  const double joint = 2.0 * (1.0 - share);
  const Eigen::AngleAxisd R(degrees * kPi / 180, Eigen::Vector3d::UnitZ());
  Eigen::Matrix3Xd out = P;
  for (int i = 0; i < n; ++i) {
    if (P(0, i) > joint) out.col(i) = R * (P.col(i) - Eigen::Vector3d(joint, 0, 0)) + Eigen::Vector3d(joint, 0, 0);
  }
  return out;
}

TEST(PoseChangeTest, ReadsTheTurnOfALimbAndNothingForARigidMotion) {
  const Eigen::Matrix3Xd rest = Bar(0.0, 0.0);
  const Eigen::Isometry3d X = Eigen::Translation3d(1, 2, 3) * Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitY());
  EXPECT_LT(PoseChangeDeg(rest, X * rest), 1e-6);
  // A limb of 15 % turned by 60 degrees: the body is the rigid fit, the limb reads 60 less
  // the little the whole's fit leans towards it.
  EXPECT_NEAR(PoseChangeDeg(rest, Bar(0.15, 60.0)), 57.0, 1.5);
}

// Every shape of the benchmark: its package is installed (scripts/install-deps), its template
// is a closed manifold the morph accepts, every target corresponds vertex by vertex and its
// pose differs by 30 degrees or more, as issue 27 asks.
class ShapeSetTest : public testing::TestWithParam<ShapeSpec> {};

}  // namespace

// GoogleTest names a parameter by this, not by its bytes.
void PrintTo(const ShapeSpec& spec, std::ostream* os) { *os << spec.name; }

namespace {

TEST_P(ShapeSetTest, TemplateIsClosedAndTargetsArePosedFarEnough) {
  const ShapeCase shape = BuildShapeCase(GetParam());
  const geometry::TopologyReport topology = geometry::AnalyzeTopology(shape.template_mesh);
  EXPECT_TRUE(topology.is_closed_manifold()) << topology.Describe();
  const Eigen::Vector3d extent =
      shape.template_mesh.V.rowwise().maxCoeff() - shape.template_mesh.V.rowwise().minCoeff();
  // The wrap lies 0.14 % of the diagonal (about 3 mm) outside the model on every side.
  EXPECT_NEAR(extent.maxCoeff(), 1.7 + 2 * 0.0014 * geometry::BoundingBoxDiagonal(shape.sources.front().V), 0.002);
  EXPECT_NO_THROW(morph::BuildTemplateModel(shape.template_mesh));
  ASSERT_EQ(shape.targets.size(), GetParam().targets.size());
  for (const ShapeTarget& target : shape.targets) {
    EXPECT_EQ(target.V.cols(), shape.template_mesh.V.cols()) << target.pair;
    EXPECT_TRUE(target.V.allFinite()) << target.pair;
    EXPECT_GE(target.pose_change_deg, 30.0) << target.pair;
  }
  ASSERT_EQ(shape.sources.size(), shape.targets.size() + 1);
}

TEST(LoadPosedModelTest, AKeyframeOfASkeletalFileOrATimePastItsAnimationIsRefused) {
  const ShapeSpec bcn = DefaultShapeSpecs().front();
  EXPECT_THROW(LoadPosedModel(bcn.file, {.label = "f3", .keyframe = 3}), InputError);
  EXPECT_THROW(LoadPosedModel(bcn.file, {.label = "late", .animation = 0, .time = 1e9}), InputError);
}

INSTANTIATE_TEST_SUITE_P(Default, ShapeSetTest, testing::ValuesIn(DefaultShapeSpecs()),
                         [](const testing::TestParamInfo<ShapeSpec>& info) { return info.param.name; });

TEST(LoadPosedModelTest, AMissingFileOrAnimationIsAnErrorNamingIt) {
  try {
    LoadPosedModel("/nonexistent/model.x", {.label = "t0", .animation = 0});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/model.x"), std::string::npos);
  }
  const ShapeSpec bcn = DefaultShapeSpecs().front();
  try {
    LoadPosedModel(bcn.file, {.label = "t0", .animation = 7});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no animation 7"), std::string::npos) << e.what();
  }
}

// A shape file in a fresh folder, for LoadShapeSpecs.
class ShapeFileTest : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("vb_shape_file_" + std::to_string(::getpid()) + "_" +
            testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path Write(const std::string& text) const {
    const std::filesystem::path path = dir_ / "shapes.yaml";
    std::ofstream(path) << text;
    return path;
  }
  // The message LoadShapeSpecs gives for @p text ("" when it reads it).
  std::string ErrorFor(const std::string& text) const {
    try {
      LoadShapeSpecs(Write(text));
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  }
  std::filesystem::path dir_;
};

constexpr const char* kHeader = "format: vbutcher-shapes\nversion: 1\nshapes:\n";

TEST_F(ShapeFileTest, ReadsBothKindsOfPoseAndFindsAModelBesideTheFile) {
  const std::vector<ShapeSpec> specs = LoadShapeSpecs(
      Write(std::string(kHeader) + "  - name: sydney_copy\n"
                                   "    family: humanoid\n"
                                   "    file: /usr/share/assimp/models/MD2/sydney.md2\n"
                                   "    rest: {label: f0, keyframe: 0}\n"
                                   "    targets:\n"
                                   "      - {label: f50, keyframe: 50}\n"
                                   "  - name: mine\n"
                                   "    family: creature\n"
                                   "    file: models/mine.x\n"
                                   "    package: none\n"
                                   "    licence: CC0\n"
                                   "    rest: {label: t0, animation: 0, time: 0}\n"
                                   "    targets:\n"
                                   "      - {label: t9, animation: 1, time: 9.5}\n"));
  ASSERT_EQ(specs.size(), 2u);
  // The same shape as the built-in one, but for its name and provenance.
  const ShapeSpec sydney = DefaultShapeSpecs()[1];
  ASSERT_EQ(sydney.name, "sydney");
  EXPECT_EQ(specs[0].file, sydney.file);
  EXPECT_EQ(specs[0].family, sydney.family);
  EXPECT_EQ(specs[0].rest.keyframe, sydney.rest.keyframe);
  EXPECT_EQ(specs[0].rest.animation, -1);
  ASSERT_EQ(specs[0].targets.size(), 1u);
  EXPECT_EQ(specs[0].targets[0].label, sydney.targets[0].label);
  EXPECT_EQ(specs[0].targets[0].keyframe, sydney.targets[0].keyframe);
  EXPECT_EQ(specs[1].file, dir_ / "models/mine.x");
  EXPECT_EQ(specs[1].licence, "CC0");
  EXPECT_EQ(specs[1].rest.animation, 0);
  EXPECT_EQ(specs[1].targets[0].animation, 1);
  EXPECT_DOUBLE_EQ(specs[1].targets[0].time, 9.5);
  EXPECT_EQ(specs[1].targets[0].keyframe, -1);
}

TEST_F(ShapeFileTest, EveryMistakeIsNamedWithItsLineAndKey) {
  const std::string shape =
      "  - name: a\n    family: humanoid\n    file: m.x\n    rest: {label: r, keyframe: 0}\n";
  struct Case {
    std::string text, expected;
  };
  const std::vector<Case> cases = {
      {"format: vbutcher-shapes\nversion: 2\nadded_in_2: 1\nshapes: []\n",
       "version: 2 is not supported"},
      {std::string(kHeader) + shape, "shapes[0].targets"},
      {std::string(kHeader) + shape + "    targets: []\n", "1 to 64 poses"},
      {std::string(kHeader) + shape +
           "    targets: [{label: t, keyframe: 1, animation: 0, time: 1}]\n",
       "either animation and time"},
      {std::string(kHeader) + shape + "    targets: [{label: t}]\n", "either animation and time"},
      {std::string(kHeader) + shape + "    targets: [{label: r, keyframe: 1}]\n",
       "'r' is used twice"},
      {std::string(kHeader) + shape + "    targets: [{label: t, keyfram: 1}]\n",
       "shapes[0].targets[0].keyfram: unknown key"},
      {std::string(kHeader) + shape + "    targets: [{label: t, animation: 0, time: -1}]\n",
       "shapes[0].targets[0].time"},
      {std::string(kHeader) + shape + "    targets: [{label: t, animation: 0}]\n",
       "shapes[0].targets[0].time"},
      {std::string(kHeader) + shape + "    targets: [{label: 't/x', keyframe: 1}]\n",
       "is not 1 to 64 letters"},
      {std::string(kHeader) + shape + "    targets: [{label: t, keyframe: 1}]\n" + shape +
           "    targets: [{label: t, keyframe: 1}]\n",
       "'a' is listed twice"},
      {std::string(kHeader) + "  - name: lamb\n    family: x\n", "shapes[0].name"},
      {std::string(kHeader) + "  - {name: b, family: h, file: '', rest: {label: r, keyframe: 0}, "
                              "targets: [{label: t, keyframe: 1}]}\n",
       "shapes[0].file: is empty"},
      {"format: vbutcher-shapes\nversion: 1\nshapes: {a: 1}\n", "expected a list of 1 to 64"},
      {std::string(kHeader) +
           "  - {name: bcn, family: h, file: m.x, rest: {label: r, keyframe: 0}, "
           "targets: [{label: t, keyframe: 1}]}\n",
       "shapes.yaml:4: shapes[0].name: 'bcn' is a built-in shape's name"},
      {std::string(kHeader) + shape +
           "    package: 'a,b'\n    targets: [{label: t, keyframe: 1}]\n",
       "shapes[0].package: 'a,b' holds a ',' or a '\"', which the CSV cannot"},
      {std::string(kHeader) + shape +
           "    licence: \"a\\tb\"\n    targets: [{label: t, keyframe: 1}]\n",
       "shapes[0].licence: 'a?b' is not up to 200 printable characters"},
      {std::string(kHeader) +
           "  - {name: b, family: h, file: 'x\"y.x', rest: {label: r, keyframe: 0}, "
           "targets: [{label: t, keyframe: 1}]}\n",
       "shapes[0].file"},
  };
  for (const Case& c : cases) {
    const std::string message = ErrorFor(c.text);
    EXPECT_NE(message.find(c.expected), std::string::npos) << c.text << "\n-> " << message;
    EXPECT_NE(message.find("shapes.yaml:"), std::string::npos) << message;
  }
}

// The held-out bodies scripts/bench runs: the file shipped reads, its licence's comma
// included (only the file and the package go into the CSV).
TEST(HeldOutShapesTest, TheShippedFileReads) {
  const std::vector<ShapeSpec> specs =
      LoadShapeSpecs(VB_SOURCE_DIR "/tools/shape_set/held_out_shapes.yaml");
  ASSERT_EQ(specs.size(), 1u);
  EXPECT_EQ(specs[0].name, "hl1man");
  EXPECT_EQ(specs[0].targets.size(), 5u);
  EXPECT_NE(specs[0].licence.find(','), std::string::npos) << specs[0].licence;
}

}  // namespace
}  // namespace vb::tools
