#include "morph/template_model.h"

#include <chrono>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "io/error.h"
#include "morph/cloud_skeleton.h"
#include "morph/mcf_skeleton.h"
#include "morph/skeleton_branches.h"

namespace vb::morph {

TemplateModelOptions::FeatureSource FeatureSourceNamed(const std::string& name,
                                                       const std::string& where) {
  if (name == "levelset") return TemplateModelOptions::FeatureSource::kLevelSet;
  if (name == "mcf") return TemplateModelOptions::FeatureSource::kMeanCurvatureFlow;
  throw InputError(where + ": '" + name + "' is neither 'levelset' nor 'mcf'");
}

TemplateModel BuildTemplateModel(const geometry::TriangleMesh& mesh,
                                 const TemplateModelOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (mesh.num_vertices() < 4 || mesh.num_faces() < 4)
    throw InputError("template: too small to be a closed mesh");
  if (!mesh.V.allFinite()) throw InputError("template: non-finite vertex coordinates");
  const geometry::TopologyReport topology = geometry::AnalyzeTopology(mesh);
  if (!topology.is_single_closed_surface()) {
    throw InputError("template: must be one closed, consistently oriented 2-manifold; it has " +
                     topology.Describe());
  }
  TemplateModel m;
  m.mesh = mesh;
  if (geometry::SignedVolume(m.mesh) < 0.0)
    m.mesh.F.row(1).swap(m.mesh.F.row(2));  // make it face outwards
  m.mesh.N = geometry::VertexNormals(m.mesh);
  m.centre = 0.5 * (mesh.V.rowwise().maxCoeff() + mesh.V.rowwise().minCoeff());
  m.size = geometry::BoundingBoxDiagonal(mesh.V);
  if (!(m.size > 0.0)) throw InputError("template: has no extent");
  m.V = (mesh.V.colwise() - m.centre) / m.size;

  geometry::TriangleMesh normalised = m.mesh;
  normalised.V = m.V;
  m.skeleton = options.feature_source == TemplateModelOptions::FeatureSource::kLevelSet
                   ? CloudSkeleton(m.V)
                   : MeanCurvatureFlowSkeleton(normalised);
  m.features = ExtractFeatureNodes(m.skeleton, options.features);
  if (m.features.num_terminals() + m.features.num_junctions() < 3) {
    throw InputError("template: its skeleton has " +
                     std::to_string(m.features.num_terminals() + m.features.num_junctions()) +
                     " feature nodes; at least three are needed to fix a pose");
  }
  m.graph = BuildDeformationGraph(normalised, options.graph);
  m.vertex_weights = VertexWeights(normalised, m.graph, options.graph);
  m.terminal_weights = PointWeights(m.features.terminals, m.features.terminal_support, m.graph,
                                    m.vertex_weights, options.graph.vertex_neighbours);
  m.limbs = MakeTemplateLimbs(m);
  m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return m;
}

TemplateLimbs MakeTemplateLimbs(const TemplateModel& model) {
  TemplateLimbs limbs;
  const std::vector<SkeletonBranch> branches = TerminalBranches(model.skeleton, model.features);
  constexpr int kSamples = TemplateLimbs::kSamples;
  limbs.rest.resize(3, static_cast<Eigen::Index>(branches.size()) * kSamples);
  std::vector<std::vector<int>> support;
  for (std::size_t a = 0; a < branches.size(); ++a) {
    limbs.length.push_back(branches[a].length());
    for (int k = 0; k < kSamples; ++k) {
      int node = 0;
      limbs.rest.col(static_cast<Eigen::Index>(a) * kSamples + k) =
          PointAlong(model.skeleton, branches[a], static_cast<double>(k) / (kSamples - 1), &node);
      support.push_back(static_cast<std::size_t>(node) < model.skeleton.support.size()
                            ? model.skeleton.support[static_cast<std::size_t>(node)]
                            : std::vector<int>{});
    }
  }
  limbs.weights = PointWeights(limbs.rest, support, model.graph, model.vertex_weights,
                               static_cast<int>(model.terminal_weights.nodes.rows()));
  const auto num_vertices = static_cast<std::size_t>(model.V.cols());
  limbs.vertex_branch.assign(num_vertices, -1);
  limbs.vertex_along.assign(num_vertices, 0.0);
  for (std::size_t a = 0; a < branches.size(); ++a) {
    const SkeletonBranch& branch = branches[a];
    if (!(branch.length() > 0)) continue;
    for (std::size_t k = 1; k < branch.nodes.size(); ++k) {
      const auto node = static_cast<std::size_t>(branch.nodes[k]);
      if (node >= model.skeleton.support.size()) continue;
      for (const int v : model.skeleton.support[node]) {
        const auto s = static_cast<std::size_t>(v);
        if (v < 0 || s >= num_vertices || limbs.vertex_branch[s] >= 0) continue;
        limbs.vertex_branch[s] = static_cast<int>(a);
        limbs.vertex_along[s] = branch.distance[k] / branch.length();
      }
    }
  }
  for (const int v : model.graph.node_vertex) {
    limbs.node_branch.push_back(limbs.vertex_branch[static_cast<std::size_t>(v)]);
    limbs.node_along.push_back(limbs.vertex_along[static_cast<std::size_t>(v)]);
  }
  return limbs;
}

}  // namespace vb::morph
