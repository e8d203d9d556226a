#include "morph/template_model.h"

#include <chrono>

#include "geometry/mesh_measures.h"
#include "geometry/mesh_topology.h"
#include "io/error.h"
#include "morph/cloud_skeleton.h"
#include "morph/mcf_skeleton.h"

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
  m.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return m;
}

}  // namespace vb::morph
