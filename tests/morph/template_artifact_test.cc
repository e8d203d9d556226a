#include "morph/template_artifact.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>

#include "io/error.h"
#include "morph/coarse_alignment.h"
#include "morph/dense_alignment.h"
#include "perception/carcass_generator.h"
#include "tests/support/lamb_fixture.h"
#include "tests/support/temp_dir.h"

namespace vb::morph {
namespace {

using ::testing::HasSubstr;

class TemplateArtifactTest : public test::LambTemplateTest {
 protected:
  // The lamb's model and annotations as an artifact, with the code's default profile.
  TemplateArtifact Lamb() const {
    TemplateArtifact artifact;
    artifact.template_id = "lamb";
    artifact.model = *model_;
    artifact.annotations = carcass_->annotations;
    return artifact;
  }
  // Saves @p artifact to @p path and loads it back: the loader's message, or "(accepted)".
  static std::string ErrorOnReload(const TemplateArtifact& artifact,
                                   const std::filesystem::path& path) {
    SaveTemplateArtifact(path, artifact);
    return LoadError(path);
  }
  static std::string LoadError(const std::filesystem::path& path) {
    try {
      LoadTemplateArtifact(path);
    } catch (const InputError& e) {
      return e.what();
    }
    return "(accepted)";
  }
};

TEST_F(TemplateArtifactTest, MorphFromTheLoadedArtifactEqualsMorphFromTheBuiltModel) {
  test::TempDir dir;
  TemplateArtifact artifact = Lamb();
  artifact.template_version = 3;
  SaveTemplateArtifact(dir / "lamb.vbt", artifact);
  const TemplateArtifact back = LoadTemplateArtifact(dir / "lamb.vbt");
  EXPECT_EQ(back.template_id, "lamb");
  EXPECT_EQ(back.template_version, 3);
  EXPECT_EQ(back.model.graph.num_nodes(), model_->graph.num_nodes());
  EXPECT_EQ(back.model.graph.nodes, model_->graph.nodes);
  EXPECT_EQ(back.model.V, model_->V);
  // The limbs are not stored but derived again on load.
  ASSERT_GT(model_->limbs.num_branches(), 0);
  EXPECT_EQ(back.model.limbs.rest, model_->limbs.rest);
  EXPECT_EQ(back.model.limbs.weights.nodes, model_->limbs.weights.nodes);
  EXPECT_EQ(back.model.limbs.weights.weights, model_->limbs.weights.weights);
  EXPECT_EQ(back.model.limbs.length, model_->limbs.length);
  EXPECT_EQ(back.model.limbs.node_branch, model_->limbs.node_branch);
  EXPECT_EQ(back.model.limbs.node_along, model_->limbs.node_along);
  EXPECT_EQ(back.model.limbs.vertex_branch, model_->limbs.vertex_branch);
  EXPECT_EQ(back.model.limbs.vertex_along, model_->limbs.vertex_along);
  ASSERT_EQ(back.annotations.cuts.size(), carcass_->annotations.cuts.size());
  EXPECT_EQ(back.annotations.cuts[1].line.size(), carcass_->annotations.cuts[1].line.size());
  EXPECT_EQ(back.annotations.parts, carcass_->annotations.parts);

  // The same target morphed with both: bit-identical results.
  const perception::PosedCarcass target =
      perception::PoseCarcass(*carcass_, perception::SampleCarcassPose(4));
  const CoarseResult a = AlignCoarse(*model_, target.mesh.V);
  const CoarseResult b = AlignCoarse(back.model, target.mesh.V);
  ASSERT_TRUE(a.ok && b.ok);
  EXPECT_EQ(a.mesh.V, b.mesh.V);
  const DenseResult da = AlignDense(*model_, a, target.mesh.V, Eigen::Matrix3Xd());
  const DenseResult db = AlignDense(back.model, b, target.mesh.V, Eigen::Matrix3Xd());
  ASSERT_TRUE(da.ok && db.ok);
  EXPECT_EQ(da.mesh.V, db.mesh.V);
}

TEST_F(TemplateArtifactTest, RefusesAnnotationsForAnotherMesh) {
  io::Annotations other = carcass_->annotations;
  other.vertex_count += 1;
  EXPECT_THROW(CompileTemplate(carcass_->mesh, other, "lamb", 1), InputError);
  EXPECT_THROW(CompileTemplate(carcass_->mesh, carcass_->annotations, "", 1), InputError);
}

TEST_F(TemplateArtifactTest, RefusesCorruptTruncatedAndForeignFiles) {
  test::TempDir dir;
  SaveTemplateArtifact(dir / "lamb.vbt", Lamb());
  std::ifstream in(dir / "lamb.vbt", std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string good = buffer.str();
  auto error = [&](const std::string& bytes) { return LoadError(dir.Write("bad.vbt", bytes)); };
  EXPECT_THAT(error(good.substr(0, good.size() - 100)), HasSubstr("checksum mismatch"));
  std::string flipped = good;
  flipped[good.size() / 3] ^= 1;
  EXPECT_THAT(error(flipped), HasSubstr("bad.vbt: checksum mismatch"));
  EXPECT_THAT(error("VBARCHV1"), HasSubstr("bad magic"));
  EXPECT_THAT(error(std::string()), HasSubstr("bad magic"));
  EXPECT_THROW(LoadTemplateArtifact(dir / "absent.vbt"), InputError);
}

TEST_F(TemplateArtifactTest, RefusesAWellFormedFileWithNonFiniteFeaturesOrSkeleton) {
  // A buggy writer's file passes its checksums; its contents must still be finite, or every
  // morph would fail on the line although `template info` and --check-config passed.
  test::TempDir dir;
  auto error = [&](const std::function<void(TemplateArtifact*)>& spoil) {
    TemplateArtifact artifact = Lamb();
    spoil(&artifact);
    return ErrorOnReload(artifact, dir / "spoilt.vbt");
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(error([&](TemplateArtifact* a) { a->model.features.terminals(1, 0) = nan; }),
              HasSubstr("spoilt.vbt: section 'features.terminals': has non-finite values"));
  EXPECT_THAT(error([&](TemplateArtifact* a) { a->model.features.junctions(0, 0) = nan; }),
              HasSubstr("section 'features.junctions': has non-finite values"));
  EXPECT_THAT(error([&](TemplateArtifact* a) { a->model.skeleton.nodes(2, 3) = nan; }),
              HasSubstr("section 'skeleton.nodes': has non-finite values"));
  EXPECT_THAT(error([&](TemplateArtifact* a) { a->model.mesh.N.col(5) *= 2; }),
              HasSubstr("section 'mesh.N': has a normal that is neither unit length nor zero"));
  EXPECT_EQ(error([](TemplateArtifact* a) { a->model.mesh.N.col(7).setZero(); }), "(accepted)");
  EXPECT_EQ(error([](TemplateArtifact*) {}), "(accepted)");
}

TEST_F(TemplateArtifactTest, RefusesAGraphWithRepeatedOrSelfJoinedNodes) {
  // The solver sums one block per pair of nodes: a node acting twice on a point, its own
  // neighbour, a bridge from a node to itself, or a point under too many nodes is refused on
  // load, with the section named.
  test::TempDir dir;
  auto error = [&](const std::function<void(TemplateArtifact*)>& spoil) {
    TemplateArtifact artifact = Lamb();
    spoil(&artifact);
    return ErrorOnReload(artifact, dir / "spoilt.vbt");
  };
  EXPECT_THAT(error([](TemplateArtifact* a) {
                NodeWeights& w = a->model.vertex_weights;
                w.nodes(1, 5) = w.nodes(0, 5);
              }),
              HasSubstr("section 'vertex_weights.nodes': lists node"));
  EXPECT_THAT(error([](TemplateArtifact* a) { a->model.graph.neighbours[3].push_back(3); }),
              HasSubstr("section 'graph.neighbours': node 3 is listed as its own neighbour"));
  EXPECT_THAT(error([](TemplateArtifact* a) {
                a->model.graph.bridges.push_back({2, 2});
              }),
              HasSubstr("joins node 2 to itself"));
  EXPECT_THAT(error([](TemplateArtifact* a) {
                NodeWeights& w = a->model.terminal_weights;
                const Eigen::Index k = w.nodes.rows();
                w.nodes.conservativeResize(kMaxNodesPerPoint + 1, Eigen::NoChange);
                w.nodes.bottomRows(kMaxNodesPerPoint + 1 - k).setConstant(-1);
                w.weights.conservativeResize(kMaxNodesPerPoint + 1, Eigen::NoChange);
                w.weights.bottomRows(kMaxNodesPerPoint + 1 - k).setZero();
              }),
              HasSubstr("section 'terminal_weights.nodes': 17 nodes a point, more than 16"));
}

TEST_F(TemplateArtifactTest, KeepsItsMorphProfileAndRefusesOneOutOfBounds) {
  test::TempDir dir;
  TemplateArtifact artifact = Lamb();
  artifact.profile.options.dense.rounds = 3;
  artifact.profile.options.coarse.articulation.keep_fraction = 0.7;
  SaveTemplateArtifact(dir / "lamb.vbt", artifact);
  const TemplateArtifact back = LoadTemplateArtifact(dir / "lamb.vbt");
  for (const ProfileKey& key : ProfileKeys())
    EXPECT_EQ(key.get(back.profile.options), key.get(artifact.profile.options)) << key.name;
  EXPECT_EQ(back.profile.options.dense.rounds, 3);

  auto error = [&](const std::function<void(MorphOptions*)>& spoil) {
    TemplateArtifact spoilt = artifact;
    spoil(&spoilt.profile.options);
    return ErrorOnReload(spoilt, dir / "spoilt.vbt");
  };
  EXPECT_THAT(error([](MorphOptions* o) { o->coarse.articulation.keep_fraction = 1.5; }),
              HasSubstr("spoilt.vbt: section 'profile.values': "
                        "coarse.articulation.keep_fraction: 1.5 is outside [0.1, 1] (fraction)"));
  EXPECT_THAT(error([](MorphOptions* o) { o->dense.association.lambda = std::nan(""); }),
              HasSubstr("dense.association.lambda: is not a finite number"));
  EXPECT_THAT(error([](MorphOptions* o) { o->dense.surface_neighbours = 100; }),
              HasSubstr("dense.surface_neighbours must not exceed dense.max_surface_neighbours"));
  EXPECT_THAT(error([](MorphOptions* o) { o->dense.max_normal_neighbours = 20; }),
              HasSubstr("dense.normal_neighbours must not exceed dense.max_normal_neighbours"));
  EXPECT_THAT(error([](MorphOptions* o) { o->dense.min_normal_neighbours = 30; }),
              HasSubstr("dense.min_normal_neighbours must not exceed dense.normal_neighbours"));
  EXPECT_THAT(error([](MorphOptions* o) { o->clean.max_points_per_vertex = 0.5; }),
              HasSubstr("clean.max_points_per_vertex must be 0 (off) or at least 1"));
}

TEST(MorphProfileTest, EveryDefaultLiesInItsBoundsAndEveryKeyIsOneMember) {
  const MorphOptions defaults;
  EXPECT_EQ(CheckProfile(defaults), "");
  std::vector<std::string> names;
  for (const ProfileKey& key : ProfileKeys()) {
    EXPECT_EQ(CheckProfileValue(key, key.get(defaults)), "") << key.name;
    EXPECT_EQ(FindProfileKey(key.name), &key);
    names.emplace_back(key.name);
    // Setting one key changes that value and no other key's.
    MorphOptions changed;
    key.set(&changed, key.max);
    for (const ProfileKey& other : ProfileKeys())
      EXPECT_EQ(other.get(changed), &other == &key ? key.max : other.get(defaults))
          << key.name << " moved " << other.name;
  }
  std::sort(names.begin(), names.end());
  EXPECT_EQ(std::adjacent_find(names.begin(), names.end()), names.end());
  EXPECT_EQ(FindProfileKey("dense.nosuch"), nullptr);
}

TEST(MorphProfileTest, SetsAKeyFromNameEqualsValueOrSaysWhyNot) {
  MorphOptions options;
  EXPECT_EQ(SetProfileKey("coarse.refit.rounds=0", &options), "");
  EXPECT_EQ(options.coarse.refit.rounds, 0);
  EXPECT_EQ(SetProfileKey("coarse.refit.keep_fraction=+0.75", &options), "");
  EXPECT_EQ(options.coarse.refit.keep_fraction, 0.75);
  EXPECT_EQ(SetProfileKey("coarse.articulation.deformation.w_rot=1e-1", &options),
            "");  // not config
  EXPECT_EQ(options.coarse.articulation.deformation.w_rot, 0.1);
  const MorphOptions before = options;
  EXPECT_EQ(SetProfileKey("coarse.refit.rounds", &options),
            "'coarse.refit.rounds': expected name=value");
  EXPECT_THAT(SetProfileKey("dense.nosuch=1", &options), HasSubstr("dense.nosuch: unknown key"));
  EXPECT_EQ(SetProfileKey("coarse.refit.rounds=", &options),
            "coarse.refit.rounds: '' is not a number");
  EXPECT_EQ(SetProfileKey("coarse.refit.rounds=3x", &options),
            "coarse.refit.rounds: '3x' is not a number");
  EXPECT_EQ(SetProfileKey("coarse.refit.rounds=inf", &options),
            "coarse.refit.rounds: 'inf' is not finite");
  EXPECT_EQ(SetProfileKey("=1", &options), "'=1': no key name before '='");
  EXPECT_THAT(SetProfileKey("coarse.refit.rounds=2.5", &options),
              HasSubstr("coarse.refit.rounds: 2.5 is not a whole number"));
  EXPECT_THAT(SetProfileKey("coarse.refit.keep_fraction=0.1", &options),
              HasSubstr("coarse.refit.keep_fraction: 0.1 is outside [0.5, 1]"));
  for (const ProfileKey& key : ProfileKeys())
    EXPECT_EQ(key.get(options), key.get(before)) << key.name << " changed by a refused setting";
}

TEST(MorphProfileTest, TheDocsCountTheKeysThereAre) {
  // Every number written just before " keys" in the method and the operations guide.
  for (const char* doc : {"docs/method.md", "docs/operations.md"}) {
    std::ifstream in(std::string(VB_SOURCE_DIR) + "/" + doc);
    ASSERT_TRUE(in) << doc;
    std::stringstream text;
    text << in.rdbuf();
    const std::string all = text.str();
    int found = 0;
    for (std::size_t at = all.find(" keys"); at != std::string::npos;
         at = all.find(" keys", at + 1)) {
      std::size_t first = at;
      while (first > 0 && std::isdigit(static_cast<unsigned char>(all[first - 1]))) --first;
      if (first == at) continue;  // words, not a count
      ++found;
      EXPECT_EQ(std::stoul(all.substr(first, at - first)), ProfileKeys().size())
          << doc << ": " << all.substr(first, at + 5 - first);
    }
    EXPECT_GE(found, 1) << doc;
  }
}

}  // namespace
}  // namespace vb::morph
