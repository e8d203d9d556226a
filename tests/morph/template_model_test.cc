#include "morph/template_model.h"

#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <vector>

#include "io/error.h"
#include "morph/mcf_skeleton.h"
#include "tests/support/implicit_shapes.h"
#include "tests/support/test_meshes.h"

namespace vb::morph {
namespace {

void ExpectRejected(const geometry::TriangleMesh& mesh, const char* fragment,
                    const TemplateModelOptions& options = {}) {
  try {
    BuildTemplateModel(mesh, options);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(TemplateModelTest, RefusesMeshesItCannotMorph) {
  geometry::TriangleMesh open = test::Box();
  open.F.conservativeResize(3, 11);
  ExpectRejected(open, "boundary edges");
  geometry::TriangleMesh flipped = test::Box();
  std::swap(flipped.F(1, 3), flipped.F(2, 3));
  ExpectRejected(flipped, "inconsistently oriented");
  geometry::TriangleMesh bad = test::Box();
  bad.V(0, 2) = std::nan("");
  ExpectRejected(bad, "non-finite");
  // A straight tube has two ends and nothing else: no pose can be read from it. (Checked
  // with the MCF skeleton: the level-set skeleton of a tube still grows spurs near its
  // root, a known gap.)
  TemplateModelOptions mcf;
  mcf.feature_source = TemplateModelOptions::FeatureSource::kMeanCurvatureFlow;
  ExpectRejected(test::CapsuleUnion({{{0, 0, 0}, {0, 0, 1}, 0.1}}, 0.03), "feature nodes", mcf);
  ExpectRejected(test::Box(), "8 points");  // too few samples for any skeleton
}

TEST(TemplateModelTest, NamesItsFeatureSources) {
  EXPECT_EQ(FeatureSourceNamed("levelset", "x"), TemplateModelOptions::FeatureSource::kLevelSet);
  EXPECT_EQ(FeatureSourceNamed("mcf", "x"),
            TemplateModelOptions::FeatureSource::kMeanCurvatureFlow);
  try {
    FeatureSourceNamed("MCF", "bench: --template-features");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "bench: --template-features: 'MCF' is neither 'levelset' nor 'mcf'");
  }
}

TEST(TemplateModelTest, NormalisesAndPrecomputesEverything) {
  geometry::TriangleMesh y = test::YShape();
  y.V = (y.V * 250.0).array() + 1000.0;  // any units, anywhere
  const TemplateModel m = BuildTemplateModel(y);
  EXPECT_NEAR((m.V.rowwise().maxCoeff() - m.V.rowwise().minCoeff()).norm(), 1.0, 1e-12);
  EXPECT_EQ(m.features.num_terminals(), 3);
  EXPECT_EQ(m.features.num_junctions(), 1);
  EXPECT_GT(m.graph.num_nodes(), 20);
  EXPECT_EQ(m.vertex_weights.nodes.cols(), y.num_vertices());
  EXPECT_EQ(m.terminal_weights.nodes.cols(), 3);
  for (Eigen::Index t = 0; t < 3; ++t)
    EXPECT_NEAR(m.terminal_weights.weights.col(t).sum(), 1.0, 1e-12);
  EXPECT_TRUE(m.mesh.has_normals());
}

// CGAL orders the edges it collapses by their addresses; the skeleton must not depend on
// what the program allocated before it.
TEST(TemplateModelTest, MeanCurvatureFlowSkeletonDoesNotDependOnTheHeap) {
  const geometry::TriangleMesh mesh = test::CapsuleUnion({{{0, 0, 0}, {0, 0, 1}, 0.12},
                                                          {{0, 0, 0.6}, {0.4, 0, 1.1}, 0.08},
                                                          {{0, 0, 0.6}, {-0.4, 0.1, 1.1}, 0.08},
                                                          {{0, 0, 0}, {0.3, 0, -0.5}, 0.09},
                                                          {{0, 0, 0}, {-0.3, 0, -0.5}, 0.09}},
                                                         0.03);
  const SkeletonGraph first = MeanCurvatureFlowSkeleton(mesh);
  // Blocks of many sizes, every other one freed: the heap's free lists now differ.
  std::mt19937 random(7);
  std::vector<std::unique_ptr<char[]>> blocks;
  for (int i = 0; i < 20000; ++i) blocks.emplace_back(new char[16 + random() % 400]);
  for (std::size_t i = 0; i < blocks.size(); i += 2) blocks[i].reset();
  const SkeletonGraph second = MeanCurvatureFlowSkeleton(mesh);
  ASSERT_GT(first.nodes.cols(), 10);
  ASSERT_EQ(first.nodes.cols(), second.nodes.cols());
  EXPECT_TRUE(first.nodes == second.nodes);
  EXPECT_EQ(first.edges, second.edges);
  EXPECT_EQ(first.support, second.support);
}

}  // namespace
}  // namespace vb::morph
